# SPDX-License-Identifier: GPL-3.0-or-later
"""The speed/accuracy trade of VSGL indirect light on demo.blend, measured against Cycles (not a test).

    .venv/bin/python benchmarks/speed_accuracy.py [--quick] [--regenerate-reference]

Writes ``benchmarks/results/speed_accuracy.md`` (``..._quick.md`` with --quick), a PNG plot of
frame time against relative RMSE and a JSON of every figure beside it; prints the same markdown.
Run time on 2 llvmpipe cores: full 12–22 min (it follows the shared machine's load), --quick ~2 min
(plus ~4 min once when the cached truth has to be rendered); of these, the flicker decomposition's
extra seeds take 70–110 s (30 frames × 2 modes × 16 seeds, 75–115 ms per image at 120x90) and the
flicker sweeps and seeds about 2 min, with --quick about 5 s and 20 s. Needs matplotlib
(requirements-dev.txt) for the plot.

The parts, one idea each: ``demo`` (the scene, the files, the log), ``truth`` (the cached Cycles
truth), ``metrics`` (error against it), ``bench`` (our passes on one G-buffer, timed), ``ours``
(our configurations measured), ``baselines`` (brute force, random VPLs, Cycles, EEVEE),
``flicker`` (temporal stability), ``memory`` (peak RSS in a fresh process), ``report``
(markdown, JSON, plot) and ``cli`` (the command line and the order of the sections).

What is measured, all at one image size (default 240x180, demo.blend's camera):

* **Ground truth**: Cycles' one-bounce indirect radiance DiffInd·DiffCol + GlossInd·GlossCol
  (max bounces 1, no denoising, adaptive sampling/light tree/clamping off, pixel filter 0.01 px so
  each pixel is its centre as in our G-buffer), the mean of two seeds, cached in
  ``benchmarks/reference/demo_indirect_<w>x<h>.npz`` (float32, compressed) with its samples, seeds,
  render times and its own noise (RMS of the seed difference / 2 = noise of the mean);
  ``--regenerate-reference`` renders it again.
* **Errors** over covered pixels (our G-buffer coverage and Cycles alpha both > 0.999), over RGB:
  RMSE noise-corrected, sqrt(mean((x − a)(x − b))) with a, b the truth's two seeds (an unbiased
  estimate of the squared error against the noise-free truth: the path tracer's caustic noise on
  this scene is large, 19 % of the mean even at 2 × 4096 samples), relative RMSE = RMSE /
  mean(truth), the plain ("measured") RMSE against the mean of the seeds, mean ratio = mean(ours) /
  mean(truth); also the diffuse-only and specular-only relative RMSE against Cycles'
  DiffInd·DiffCol and GlossInd·GlossCol.
* **Ours**: N ∈ {2-VSGL, 64, 256, 1024, 4096} × K ∈ {1, 4} × kernel {modified, original} × RSM
  {64², 128², 256²} (2-VSGL has no N/K/kernel choice), with the add-on's default per-lobe positions;
  and, to show what that choice does, the paper's shared positions (000 app. B.2) for both kernels,
  K = 1, RSM 128² (64² with --quick), every N. Per-material breakdown (floor, walls, sphere) of the
  squared error and mean ratio for the demo settings in both positional distributions. The G-buffer and shading inputs are made
  once; per configuration: RSM + VSGL generation (GPU finished) and VSGL shading (GPU finished,
  median of --repeats). "frame" = that + the fixed passes of a full FrameRenderer frame (scene
  upload, G-buffer, direct light, read-back), measured once.
* **Brute force**: every RSM texel as its own VSGL (``reference.vsgl_shading.per_texel_vsgls``),
  uploaded as tables of 4096 and blended, shaded by the same pass.
* **Random VPLs**: N texels drawn with replacement from the same PDF as VSGL generation
  (luminance of Φ(Rd + Rs), ``reference.vsgl.default_pdf``), each texel's moments scaled by
  1/(N p) (unbiased), made into per-texel VSGLs and shaded by the same pass: same shader and count,
  so equal shading time to our N (both measured). Mean RMSE over 3 seeds.
  Their "frame" = fixed passes + RSM alone + shading (the CPU sampling is not counted).
* **Cycles** at 1, 2, 4, … 2048 samples (seed distinct from the truth's), render wall time (bpy.ops
  render incl. scene sync and EXR write) and RMSE against the truth; the time Cycles needs to
  reach each of our RMSEs, interpolated log-log between sample counts.
* **EEVEE** at the scene's settings: its indirect = Combined(as saved) − Combined(with every
  indirect source off: ray tracing and fast GI off, world black, no light probes). The defaults
  have ray tracing off, so EEVEE's default indirect in this scene (black world, no probes) is zero;
  also measured: ray tracing on (screen-space tracing with fast GI), indirect = Combined(on) −
  Combined(off). Timed on a second render (the first compiles shaders).
* **Temporal stability**: 30 frames of the spot turning 1° per frame about the
  world Z axis, N = 256, K = 1, RSM 128², seed 0, at half the image size; mean absolute
  frame-to-frame change (over covered pixels and RGB) per kernel mode (the flicker target's measure, the
  verdict's), also relative to the mean indirect, and the mean absolute second difference
  |I(t+1) − 2I(t) + I(t−1)| ("jitter": a change smooth in time cancels, jumps remain). Context:
  2-VSGL and brute force (every texel of a 64² RSM as a VPL). Decomposition (context, not the
  verdict): for the modified and original kernels each frame is also rendered with lattice seeds
  1..S (S = 16), whose mean Ī(t) estimates that mode's expected image over the random lattice
  rotation (its converged image, blur included; smooth in time); "motion" = mean |Ī(t) − Ī(t−1)|
  (the lighting's real change as the mode sees it), "flicker proper" = mean |e(t) − e(t−1)| with
  e = I − Ī (the change of the seed-0 image's sampling error). Ī keeps a residual sampling error of
  1/√S of one seed's; seed 0 is not in Ī, so e has (1 + 1/S) times the variance of I's own error
  (flicker proper reads high by about √(1 + 1/S), ~3 % at S = 16, equally for both modes, so it
  cancels in their ratio); reported, not rescaled. Motion floor = modified motion / original
  change: the seed-0 image is Ī + e with e of zero mean over the lattice rotation, so (Jensen) its
  expected change is at least the motion, and the modified kernel's change ratio cannot be expected
  below that figure however little it flickers.
  Sweeps (seed 0, both kernels, no decomposition), at N ∈ {64, 256, 1024} with K = 1 and RSM 128²,
  N = 256 with K = 4, N = 256 with RSM 64² and 256², and N = 256 with the paper's shared positions
  (the rest per-lobe, the add-on's default): the same turn ("pan"), and a "spin" of the spot
  1°/frame about its own cone axis, which leaves the lighting the same in every frame (a round cone) while the RSM and its PDF rotate under the fixed lattice, so
  all of its change is flicker. The target's measure has a verdict for each turn at the section's
  settings (N = 256, K = 1, RSM 128²): the median over lattice seeds 0–4 (the original kernel's
  spikes come and go with the seed).
* **Peak memory**: a fresh subprocess renders a 1024² frame with N = 4096 (RSM 256²) with the
  FrameRenderer; peak RSS = the process's VmHWM (/proc/self/status), with its value before the
  render. (getrusage's ru_maxrss is not used for the verdict: after fork + exec it carries the
  forking parent's high-water mark.)
* **NaN/Inf**: every raw shading output above (before the renderer's nan_to_num) and a few
  parameter extremes (N = 1 / 4096, K = 0.25 / 16, RSM 1² / 256²).

``--quick`` (a smoke test): N ∈ {2-VSGL, 64, 256}, K = 1, both kernels, RSM 64² only; brute force
at 64²; random VPLs (1 seed) at 64²; Cycles up to 16 samples; one EEVEE render (as saved);
8 flicker frames without the brute force, decomposition with S = 4 seeds, sweeps at N ∈ {64, 256},
K = 1, seeds 0–2; memory at 1024² with N = 256 (no verdict).
"""
