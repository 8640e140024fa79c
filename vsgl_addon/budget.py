# SPDX-License-Identifier: GPL-3.0-or-later
"""The time budget: a frame's settings chosen from a target frame time and a cost model of this machine.

bpy-free and GPU-free (the caller renders). Three parts:

* **Features**: :func:`frame_features` turns a frame plan (planner.plan_frame) and candidate settings
  into the quantities each timed step's cost is linear in (``STEP_FEATURES``): pixels, pixels × VSGLs
  for the shading, RSM texels × VSGL sets for the light passes, shadow-map splats, tested and culled
  VPLs per pixel for the VPL pass, and so on. A step the plan does not run has no features, hence no cost.
* **Cost model**: :class:`CostModel` holds per step one non-negative coefficient per feature (seconds),
  fitted by non-negative least squares to per-pass timings measured on this machine
  (FrameImages.timings: a short calibration at first use, :data:`CALIBRATION`, and the budgeted
  frames since), pulled towards the built-in coefficients (:data:`FALLBACK_COEFFICIENTS`, measured on
  the reference machine) where the samples do not determine a coefficient (a pass the calibration
  scene never ran). It is kept in the user's cache directory (:func:`cache_path`), one model per GPU,
  never in the .blend; a missing file means the built-in model, an unreadable one the same with one
  warning.
* **Choice**: :func:`choose` walks one path of settings from the cheapest (N = 16, RSM 32², δ = 0.1,
  8 × 8 interleave, quarter resolution) to the richest, each step raising the one parameter whose
  predicted error falls most per predicted second (:func:`predicted_error`), and takes the last point
  of the path whose predicted frame time fits the target. The path does not depend on the target, so
  a larger target never gets a lower setting of any parameter (monotone in the budget). The passes
  are the plan's: in Budget mode the planner weighs the VPL pass and MRP-ASG as in Auto
  (planner.WEIGHING_MODES), and the chosen settings pin its decisions.
"""

from __future__ import annotations

import itertools
import json
import math
import os
import sys
import tempfile
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from .views import rsm_size_for_share
from .settings import VSGLSettings, interleave_factor

#: The features each timed step (its FrameImages.timings key) is linear in. Units keep the
#: coefficients near milliseconds: pixels in 10⁵, VSGLs in 10³, texels in 10⁵, splats in 10⁶.
STEP_FEATURES = {
    "upload": ("one", "triangles"),
    "rsm_and_vsgl_generation": ("rsm_views", "rsm_texels", "vsgls"),
    "ism": ("vsgls", "ism_splats", "ism_texels"),
    "vpl_extraction": ("vpl_views", "vpl_texels"),
    "mrp_visibility": ("proxies",),
    "gbuffer": ("one", "pixels", "triangles"),
    "direct_light": ("pixels", "pixel_lights"),
    "vsgl_shading": ("pixels", "vsgls", "pixel_vsgls"),
    "vpl_culling": ("pixels", "pixel_vpls", "pixel_vpl_tests"),
    "mrp_asg": ("pixels", "pixel_proxies"),
    "read_back": ("pixels",),
    "upscale": ("full_pixels",),
}

#: Seconds per feature unit, fitted on the reference machine (2 shared cores, llvmpipe 256 bits) by
#: benchmarks/cost_model_fit.py (committed results/cost_model_fit.md): budget_render.CALIBRATION's
#: frames of the eleven scenes of the validation suite at 240x180 and the VPL pass's interleave
#: sweeps, 125 frames; predicted / measured frame time 0.55 to 1.30, median 0.97, before any scene's
#: correction (the coefficients before them predicted 1.6 to 10× the measured frames): the model
#: when no cache exists, Auto's weighing of the passes, and the prior of every fit.
FALLBACK_COEFFICIENTS = {
    "upload": (1.5e-4, 3.1e-2),
    "rsm_and_vsgl_generation": (1.0e-3, 4.7e-2, 7.2e-3),
    "ism": (0.13, 3.2e-2, 3.2e-2),
    "vpl_extraction": (5.3e-3, 0.18),
    "mrp_visibility": (2.5e-4,),
    "gbuffer": (3.0e-4, 4.7e-3, 6.0e-2),
    "direct_light": (4.6e-4, 2.0e-2),
    "vsgl_shading": (3.7e-2, 6.1e-2, 1.4),
    "vpl_culling": (0.17, 7.1e-2, 2.2e-2),
    "mrp_asg": (1.5e-2, 5.0e-3),
    "read_back": (1.8e-3,),
    "upscale": (1.2e-2,),
}

#: Seconds per 10⁵ of the region's pixels of the viewport's joint bilateral resolve in one pass
#: (view_gpu.py, six images with shared weights; a new coarse size resolves so): 1311 x 786 took
#: 30-38 ms alone in the bpy module and 26-33 ms in Blender 5.2 (benchmarks/results/resolve_weights*.md),
#: 33-50 ms inside the coarse step. Not a step of F12's frames, so no calibration frame fits it.
VIEW_RESOLVE_SECONDS = 4.0e-3

#: Culled VPLs per pixel against δ, relative to δ = 10⁻³: benchmarks/results/vpl_caustics.md's
#: "listed per pixel" on caustic_panel (2806, 1923, 1242, 346 at δ = 10⁻⁵ … 10⁻²; 004 Eq. 2's
#: acceptance bound shrinks as δ grows), interpolated log-log, extended to 10⁻¹ with the last slope.
_DELTA_LISTED = ((1e-5, 2806.0 / 1242.0), (1e-4, 1923.0 / 1242.0), (1e-3, 1.0), (1e-2, 346.0 / 1242.0),
                 (1e-1, (346.0 / 1242.0) ** 2))

#: VPLs per RSM texel of the VPL pass's views when no frame of the scene has counted them yet.
DEFAULT_VPL_FRACTION = 0.1

#: Frames of measured timings the cache keeps per model (the most recent ones).
MAX_SAMPLES = 64
#: Weight of the prior (built-in coefficients) in a fit, as a number of samples' worth per coefficient.
PRIOR_WEIGHT = 0.05

#: 2: the VPL pass's tested VPLs per pixel (STEP_FEATURES["vpl_culling"]), a third feature.
CACHE_FORMAT = 2
CACHE_NAME = "cost_model.json"

# The choice's parameters, cheapest first (the path starts at each list's first value).
VSGL_COUNTS = (16, 24, 32, 48, 64, 96, 128, 192, 256, 384, 512, 768, 1024, 1536, 2048, 3072, 4096)
RSM_SIZES = (32, 64, 128, 256, 512)
DELTAS = (1e-1, 3e-2, 1e-2, 3e-3, 1e-3, 1e-4)
INTERLEAVES = ("8", "4", "2", "1")
SCALES = (0.25, 0.5, 0.75, 1.0)


def delta_listed(delta: float) -> float:
    """Culled VPLs per pixel at ``delta`` relative to δ = 10⁻³ (``_DELTA_LISTED``, log-log)."""
    logs = np.log10([d for d, _ in _DELTA_LISTED])
    values = np.log10([v for _, v in _DELTA_LISTED])
    x = math.log10(min(max(float(delta), 1e-6), 1e-1))
    slope_low = (values[1] - values[0]) / (logs[1] - logs[0])
    if x < logs[0]:
        return float(10.0 ** (values[0] + slope_low * (x - logs[0])))
    return float(10.0 ** np.interp(x, logs, values))


# --- Features -------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Candidate:
    """What the budget chooses: VSGL count, RSM side, δ, VPL interleave, resolution scale."""

    vsgl_count: int
    rsm_size: int
    delta: float
    vpl_interleave: str
    scale: float

    def apply(self, settings: VSGLSettings) -> VSGLSettings:
        return replace(settings, vsgl_count=self.vsgl_count, rsm_size=self.rsm_size, delta=self.delta,
                       vpl_interleave=self.vpl_interleave)


def scaled_size(width: int, height: int, scale: float) -> tuple[int, int]:
    """The rendered size at ``scale`` of width × height (each side at least one pixel)."""
    return max(int(round(width * scale)), 1), max(int(round(height * scale)), 1)


def frame_features(plan, settings: VSGLSettings, size: tuple[int, int], full_size: tuple[int, int] | None = None,
                   triangles: int = 0, vpl_fraction: float | None = None, vpl_stride: int = 1) -> dict:
    """step -> (k,) float64 features of one frame of ``plan`` rendered with ``settings`` at ``size``
    (w, h), upscaled to ``full_size`` when that differs; ``triangles``: the scene's. The lights' RSM
    sides follow the plan's rule for the settings' side (views.rsm_size_for_share of their bounce
    estimates); ``vpl_fraction``: VPLs per RSM texel of the VPL pass's views (a frame of the scene
    counted them), DEFAULT_VPL_FRACTION when unknown; ``vpl_stride``: the VPL pass shades one VPL
    of each block of that many (the viewport's coarse preview)."""
    w, h = size
    full_width, full_height = full_size or size
    pixels = w * h / 1e5
    rsm_lights = [light for light in plan.lights if light.gets_rsm]
    total = sum(light.bounce_estimate for light in rsm_lights)
    views = texels = 0.0
    for light in rsm_lights:
        side = settings.rsm_size
        if settings.kernel != "two-vsgl" and total > 0.0:
            side = rsm_size_for_share(settings.rsm_size, light.bounce_estimate / total)
        views += light.rsm_views
        texels += light.rsm_views * side * side
    sets = len(plan.receiver_sets)
    runs = plan.runs
    if not runs("vsgls"):
        vsgls = 0.0
    elif settings.kernel == "two-vsgl":
        vsgls = 2.0 * views * sets
    else:
        # Each set's share of N (planner.FramePlan.set_budget: the glossy receivers' set may have more).
        budget = getattr(plan, "vsgl_budget", 0)
        shares = [plan.set_budget(name) / budget if budget and hasattr(plan, "set_budget") else 1.0
                  for name in plan.receiver_sets]
        vsgls = float(settings.vsgl_count * sum(shares))
    proxies = float(len(plan.proxies))
    out = {
        "upload": (1.0, triangles / 1e5),
        "rsm_and_vsgl_generation": (views * sets, texels * sets / 1e5, vsgls / 1e3),
        "gbuffer": (1.0, pixels, triangles / 1e5),
        "direct_light": (pixels, pixels * len(rsm_lights)),
        "vsgl_shading": (pixels, vsgls / 1e3, pixels * vsgls / 1e3),
        "read_back": (pixels,),
        "upscale": ((full_width * full_height / 1e5) if (w, h) != (full_width, full_height) else 0.0,),
    }
    if runs("visibility"):
        out["ism"] = (vsgls / 1e3, vsgls * settings.ism_points / 1e6,
                      vsgls * settings.ism_size * settings.ism_size / 1e6)
    if runs("vpl_pass"):
        vpl_views = sum(light.rsm_views for light in rsm_lights)
        vpl_texels = vpl_views * settings.rsm_size * settings.rsm_size
        fraction = DEFAULT_VPL_FRACTION if vpl_fraction is None else vpl_fraction
        factor = interleave_factor(settings.vpl_interleave, w, h)
        stride = max(int(vpl_stride), 1)
        # Every tile tests every (strided) VPL's spheroid, whatever the interleave; a pixel shades
        # only the listed VPLs of its sub-image (vpl_cull_shade.comp.glsl).
        tested = fraction * vpl_texels / stride
        listed = tested * delta_listed(settings.delta) / (factor * factor)
        out["vpl_extraction"] = (float(vpl_views), vpl_texels / 1e5)
        out["vpl_culling"] = (pixels, pixels * settings.vpl_samples * listed / 1e3,
                              pixels * settings.vpl_samples * tested / 1e3)
    if runs("mrp_asg") and proxies:
        if settings.visibility:
            out["mrp_visibility"] = (proxies,)
        out["mrp_asg"] = (pixels, pixels * proxies)
    return {step: np.asarray(values, np.float64) for step, values in out.items()}


# --- The cost model -------------------------------------------------------------------------------


def nnls(matrix, target) -> np.ndarray:
    """argmin ||A x − b|| over x ≥ 0, exactly, by trying every set of free coefficients (the steps
    have at most three features, so at most seven least-squares solves)."""
    matrix = np.asarray(matrix, np.float64)
    target = np.asarray(target, np.float64)
    k = matrix.shape[1]
    best, best_residual = np.zeros(k), float(np.sum(target * target))
    for size in range(1, k + 1):
        for free in itertools.combinations(range(k), size):
            solution, *_ = np.linalg.lstsq(matrix[:, free], target, rcond=None)
            if np.any(solution < 0.0) or not np.all(np.isfinite(solution)):
                continue
            x = np.zeros(k)
            x[list(free)] = solution
            residual = float(np.sum((matrix @ x - target) ** 2))
            if residual < best_residual - 1e-18 * max(best_residual, 1.0):
                best, best_residual = x, residual
    return best


#: Scenes whose per-step corrections the cache keeps (the most recently rendered).
MAX_SCENES = 32
#: Where a scene's corrections keep its VPLs per RSM texel (not a step: predictions never read it).
VPL_FRACTION_KEY = "vpls_per_texel"
#: Weight of a new frame in a scene's per-step correction (an exponential moving average).
CORRECTION_WEIGHT = 0.5
#: A correction stays within these factors (one disturbed frame of a shared machine cannot make it wild).
CORRECTION_RANGE = (0.25, 4.0)


@dataclass
class CostModel:
    """Per step, seconds per feature unit (STEP_FEATURES); ``samples``: the measured frames it was
    fitted to ({"features": step -> list, "timings": step -> seconds}); ``source`` says which.

    ``corrections``: scene key -> step -> measured / predicted seconds of that scene's recent frames
    (an average, CORRECTION_WEIGHT for the newest): what one linear model of all scenes misses of one
    (a scene's materials change the shading's cost per pixel and VSGL, its lights the ISM's)."""

    coefficients: dict
    source: str = "built-in (no calibration in the cache)"
    samples: list = field(default_factory=list)
    warning: str | None = None
    corrections: dict = field(default_factory=dict)

    @classmethod
    def fallback(cls, warning: str | None = None) -> "CostModel":
        return cls({step: list(values) for step, values in FALLBACK_COEFFICIENTS.items()}, warning=warning)

    def predict_steps(self, features: dict, scene: str | None = None) -> dict:
        """step -> predicted seconds; with ``scene`` (a key), times that scene's correction."""
        corrections = self.corrections.get(scene, {}) if scene is not None else {}
        return {step: float(np.dot(self.coefficients.get(step, FALLBACK_COEFFICIENTS[step]), values))
                * corrections.get(step, 1.0) for step, values in features.items()}

    def predict(self, features: dict, scene: str | None = None) -> float:
        """Predicted frame time in seconds (the sum of its steps)."""
        return float(sum(self.predict_steps(features, scene).values()))

    def with_samples(self, samples: list, source: str) -> "CostModel":
        """The model fitted to ``samples`` (the last MAX_SAMPLES), the built-in coefficients as prior."""
        samples = list(samples)[-MAX_SAMPLES:]
        return CostModel(fit(samples), source, samples, corrections=dict(self.corrections))

    def add_frame(self, features: dict, timings: dict, scene: str | None = None) -> "CostModel":
        """This model refitted with one more measured frame (the recent frames), and with ``scene``,
        that scene's corrections updated by it (:meth:`correct`)."""
        sample = {"features": {step: [float(v) for v in values] for step, values in features.items()},
                  "timings": {step: float(timings.get(step, 0.0)) for step in features}}
        source = self.source if self.source.startswith("fitted") else "fitted to this machine's frames"
        model = self.with_samples([*self.samples, sample], source)
        if scene is not None:
            model.correct(features, timings, scene)
        return model

    def correct(self, features: dict, timings: dict, scene: str) -> None:
        """Move ``scene``'s per-step corrections towards this frame's measured / predicted seconds."""
        predicted = self.predict_steps(features)
        old = self.corrections.pop(scene, {})
        new = dict(old)
        for step, seconds in predicted.items():
            if seconds > 1e-4 and step in timings:
                ratio = min(max(float(timings[step]) / seconds, CORRECTION_RANGE[0]), CORRECTION_RANGE[1])
                previous = old.get(step)
                new[step] = ratio if previous is None else (
                    CORRECTION_WEIGHT * ratio + (1.0 - CORRECTION_WEIGHT) * previous)
        self.corrections[scene] = new  # last in the dict: the most recent
        while len(self.corrections) > MAX_SCENES:
            self.corrections.pop(next(iter(self.corrections)))

    def vpl_fraction(self, scene: str) -> float | None:
        """VPLs per RSM texel of the VPL pass's views that ``scene``'s last frame counted (None: none yet)."""
        return self.corrections.get(scene, {}).get(VPL_FRACTION_KEY)

    def set_vpl_fraction(self, scene: str, fraction: float) -> None:
        self.corrections.setdefault(scene, {})[VPL_FRACTION_KEY] = float(fraction)

    def to_dict(self) -> dict:
        return {"coefficients": {step: [float(v) for v in values] for step, values in self.coefficients.items()},
                "source": self.source, "samples": self.samples, "corrections": self.corrections}

    @classmethod
    def from_dict(cls, data: dict) -> "CostModel":
        coefficients = {}
        for step, values in FALLBACK_COEFFICIENTS.items():
            stored = data["coefficients"].get(step, values)
            if len(stored) != len(values) or not all(math.isfinite(float(v)) and float(v) >= 0.0 for v in stored):
                raise ValueError(f"step {step!r}: {len(values)} non-negative coefficients expected, got {stored!r}")
            coefficients[step] = [float(v) for v in stored]
        samples = data.get("samples", [])
        if not isinstance(samples, list):
            raise ValueError("samples must be a list")
        corrections = {str(scene): {str(step): float(value) for step, value in steps.items()}
                       for scene, steps in data.get("corrections", {}).items()}
        return cls(coefficients, str(data.get("source", "cache")), samples, corrections=corrections)


def fit(samples: list, prior: dict | None = None) -> dict:
    """step -> coefficients ≥ 0 minimising the squared error of each step's predicted seconds over
    ``samples``, plus PRIOR_WEIGHT samples' worth of pull towards ``prior`` per coefficient (each
    feature's pull scaled by its RMS over the samples, so a feature the samples never had keeps the
    prior exactly and a well-measured one follows the data)."""
    prior = FALLBACK_COEFFICIENTS if prior is None else prior
    out = {}
    for step, names in STEP_FEATURES.items():
        rows, times = [], []
        for sample in samples:
            values = sample["features"].get(step)
            if values is None:
                continue
            rows.append(np.asarray(values, np.float64))
            times.append(float(sample["timings"].get(step, 0.0)))
        theta0 = np.asarray(prior[step], np.float64)
        if not rows:
            out[step] = [float(v) for v in theta0]
            continue
        matrix, times = np.array(rows), np.array(times)
        scale = np.sqrt(np.mean(matrix * matrix, axis=0))
        weight = math.sqrt(PRIOR_WEIGHT)
        prior_rows = np.diag(weight * scale)
        augmented = np.vstack([matrix, prior_rows[scale > 0.0]])
        targets = np.concatenate([times, (weight * scale * theta0)[scale > 0.0]])
        solution = nnls(augmented, targets)
        solution[scale == 0.0] = theta0[scale == 0.0]
        out[step] = [float(v) for v in solution]
    return out


def cache_dir() -> Path:
    """The user's cache directory for the add-on: $XDG_CACHE_HOME/vsgl-addon (~/.cache/vsgl-addon),
    %LOCALAPPDATA%\\vsgl-addon on Windows, ~/Library/Caches/vsgl-addon on macOS."""
    if os.environ.get("XDG_CACHE_HOME"):
        base = Path(os.environ["XDG_CACHE_HOME"])
    elif sys.platform == "win32" and os.environ.get("LOCALAPPDATA"):
        base = Path(os.environ["LOCALAPPDATA"])
    elif sys.platform == "darwin":
        base = Path.home() / "Library" / "Caches"
    else:
        base = Path.home() / ".cache"
    return base / "vsgl-addon"


def cache_path() -> Path:
    return cache_dir() / CACHE_NAME


def load_model(gpu: str, path: Path | None = None) -> CostModel:
    """The cached model of ``gpu`` (the GPU renderer's name), or the built-in one: silently when the
    cache has none or was written by an earlier version (an older ``format``, whose features differ:
    the caller recalibrates and replaces it), with one ``warning`` (model.warning) when the file
    cannot be read."""
    path = cache_path() if path is None else Path(path)
    if not path.is_file():
        return CostModel.fallback()
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
        written = data.get("format")
        if isinstance(written, int) and not isinstance(written, bool) and 1 <= written < CACHE_FORMAT:
            return CostModel.fallback()
        if written != CACHE_FORMAT:
            raise ValueError(f"format {written!r}, expected {CACHE_FORMAT}")
        models = data["models"]
        if gpu not in models:
            return CostModel.fallback()
        return CostModel.from_dict(models[gpu])
    except (OSError, ValueError, KeyError, TypeError, AttributeError) as error:
        return CostModel.fallback(f"VSGL: the cost model cache {path} is unreadable ({type(error).__name__}: "
                                  f"{error}); using the built-in cost model")


def save_model(gpu: str, model: CostModel, path: Path | None = None) -> Path:
    """Write ``model`` as ``gpu``'s into the cache (other GPUs' models kept; an unreadable file replaced),
    atomically."""
    path = cache_path() if path is None else Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
        if data.get("format") != CACHE_FORMAT or not isinstance(data.get("models"), dict):
            raise ValueError
    except (OSError, ValueError, AttributeError):
        data = {"format": CACHE_FORMAT, "models": {}}
    data["models"][gpu] = model.to_dict()
    handle, temporary = tempfile.mkstemp(dir=path.parent, prefix=".cost_model.", suffix=".json")
    with os.fdopen(handle, "w", encoding="utf-8") as file:
        json.dump(data, file)
    os.replace(temporary, path)
    return path


# --- The choice -----------------------------------------------------------------------------------

#: The predicted relative RMSE terms the path trades against time. Rough, from measurements:
#: VSGLs a·N^(-1/2) (speed_accuracy.md: demo rel RMSE 1.00 / 0.62 / 0.56 at N = 64 / 256 / 1024, the
#: sampling part of a clustering estimate), RSM side b/R (the same table: 0.65 -> 0.62 from 64² to
#: 128² at N = 256), the VPLs' noise c·√(listed⁻¹) × interleave (vpl_caustics.md: 0.085 -> 0.101 from
#: δ = 10⁻³ to 10⁻²; each pixel sees 1/I² of the VPLs), resolution d·(1/scale − 1) (upsampling blurs
#: edges; weighted so a lower resolution is the last resort: halving it costs more than N 256 -> 64).
ERROR_WEIGHTS = {"vsgls": 4.0, "rsm": 2.0, "vpls": 0.01, "scale": 0.3}


def predicted_error(candidate: Candidate, vpl_pass: bool) -> float:
    error = ERROR_WEIGHTS["vsgls"] / math.sqrt(candidate.vsgl_count) + ERROR_WEIGHTS["rsm"] / candidate.rsm_size
    if vpl_pass:
        error += (ERROR_WEIGHTS["vpls"] * int(candidate.vpl_interleave)
                  / math.sqrt(delta_listed(candidate.delta)))
    return error + ERROR_WEIGHTS["scale"] * (1.0 / candidate.scale - 1.0)


@dataclass
class BudgetChoice:
    """The settings Budget mode renders with, and what the model predicted for them."""

    target_seconds: float
    candidate: Candidate
    settings: VSGLSettings
    predicted_seconds: float
    predicted_steps: dict
    size: tuple  # the rendered width, height
    full_size: tuple
    step: int  # position on the path (0: the cheapest)
    steps: int
    model_source: str
    fits: bool  # predicted within the target
    measured_seconds: float | None = None
    warning: str | None = None

    def line(self) -> str:
        c = self.candidate
        measured = "" if self.measured_seconds is None else f", measured {self.measured_seconds * 1e3:.0f} ms"
        verdict = "" if self.fits else " (the cheapest setting; the target cannot be met)"
        return (f"Budget: on — target {self.target_seconds * 1e3:.0f} ms, predicted "
                f"{self.predicted_seconds * 1e3:.0f} ms{measured}{verdict}: N = {c.vsgl_count}, RSM {c.rsm_size}², "
                f"δ = {c.delta:g}, interleave {c.vpl_interleave}×{c.vpl_interleave}, "
                f"{self.size[0]}x{self.size[1]} of {self.full_size[0]}x{self.full_size[1]} "
                f"(step {self.step + 1} of {self.steps}; cost model: {self.model_source})")

    def to_dict(self) -> dict:
        c = self.candidate
        return {"target_ms": self.target_seconds * 1e3, "predicted_ms": self.predicted_seconds * 1e3,
                "measured_ms": None if self.measured_seconds is None else self.measured_seconds * 1e3,
                "predicted_steps_ms": {k: v * 1e3 for k, v in self.predicted_steps.items()},
                "vsgl_count": c.vsgl_count, "rsm_size": c.rsm_size, "delta": c.delta,
                "vpl_interleave": c.vpl_interleave, "resolution_scale": c.scale,
                "rendered_size": list(self.size), "size": list(self.full_size), "path_step": self.step,
                "path_steps": self.steps, "fits": self.fits, "cost_model": self.model_source,
                "warning": self.warning}


def predicted_seconds(plan, settings: VSGLSettings, candidate: Candidate, width: int, height: int, model: CostModel,
                      triangles: int = 0, vpl_fraction: float | None = None, scene: str | None = None) -> float:
    """The model's frame time of ``candidate`` at width × height (its scale's size, upscaled)."""
    features = frame_features(plan, candidate.apply(settings), scaled_size(width, height, candidate.scale),
                              (width, height), triangles, vpl_fraction)
    return model.predict(features, scene)


def path(plan, settings: VSGLSettings, width: int, height: int, model: CostModel, triangles: int = 0,
         vpl_fraction: float | None = None, scene: str | None = None) -> list[tuple[Candidate, float]]:
    """(candidate, predicted seconds) from the cheapest setting to the richest: each step raises one
    parameter one level, the one with the largest fall of predicted_error per predicted second."""
    vpl_pass = plan.runs("vpl_pass")
    levels = {"vsgl_count": VSGL_COUNTS, "rsm_size": RSM_SIZES, "scale": SCALES}
    if vpl_pass:
        levels.update(delta=DELTAS, vpl_interleave=INTERLEAVES)
    fixed = {"delta": settings.delta, "vpl_interleave": settings.vpl_interleave}
    if settings.kernel == "two-vsgl":
        levels["vsgl_count"] = (settings.vsgl_count,)  # two per view (003): N is not used

    def make(index):
        values = {name: levels[name][i] for name, i in index.items()}
        return Candidate(**{**fixed, **values})

    def cost(candidate):
        return predicted_seconds(plan, settings, candidate, width, height, model, triangles, vpl_fraction, scene)

    index = {name: 0 for name in levels}
    current = make(index)
    steps = [(current, cost(current))]
    while True:
        best = None
        for name in levels:
            if index[name] + 1 >= len(levels[name]):
                continue
            trial = dict(index, **{name: index[name] + 1})
            candidate = make(trial)
            seconds = cost(candidate)
            gain = predicted_error(current, vpl_pass) - predicted_error(candidate, vpl_pass)
            rate = gain / max(seconds - steps[-1][1], 1e-6)
            if best is None or rate > best[0]:
                best = (rate, trial, candidate, seconds)
        if best is None:
            return steps
        _, index, current, seconds = best
        steps.append((current, seconds))


def choose(plan, settings: VSGLSettings, width: int, height: int, target_ms: float, model: CostModel,
           triangles: int = 0, vpl_fraction: float | None = None, scene: str | None = None) -> BudgetChoice:
    """The last setting of :func:`path` whose predicted frame time is within ``target_ms`` (the first
    when none is). When the path's next step only raises N, N is raised towards it as far as the
    target allows (the path's levels are 1.5x apart, so a frame would otherwise leave up to a third of
    its budget unused); below that next level, so the choice stays monotone in the target."""
    target = float(target_ms) / 1e3
    steps = path(plan, settings, width, height, model, triangles, vpl_fraction, scene)
    fitting = [i for i, (_, seconds) in enumerate(steps) if seconds <= target]
    position = max(fitting) if fitting else 0
    candidate, seconds = steps[position]
    if fitting and position + 1 < len(steps):
        following = steps[position + 1][0]
        if replace(following, vsgl_count=candidate.vsgl_count) == candidate:
            low, high = candidate.vsgl_count, following.vsgl_count  # cost(low) fits, cost(high) does not
            while high - low > 1:
                middle = (low + high) // 2
                trial = replace(candidate, vsgl_count=middle)
                if predicted_seconds(plan, settings, trial, width, height, model, triangles, vpl_fraction,
                                     scene) <= target:
                    low = middle
                else:
                    high = middle
            if low != candidate.vsgl_count:
                candidate = replace(candidate, vsgl_count=low)
                seconds = predicted_seconds(plan, settings, candidate, width, height, model, triangles,
                                            vpl_fraction, scene)
    # The plan's passes, fixed (planner.FramePlan.pinned), so the frame runs what the path's times
    # were predicted for.
    chosen = plan.pinned(candidate.apply(settings))
    size = scaled_size(width, height, candidate.scale)
    features = frame_features(plan, chosen, size, (width, height), triangles, vpl_fraction)
    return BudgetChoice(target, candidate, chosen, seconds, model.predict_steps(features, scene), size, (width, height),
                        position, len(steps), model.source, bool(fitting), warning=model.warning)


def upscale(image: np.ndarray, width: int, height: int) -> np.ndarray:
    """(h, w, ...) -> (height, width, ...) by bilinear interpolation at pixel centres (edges clamped)."""
    image = np.asarray(image)
    h, w = image.shape[:2]
    if (h, w) == (height, width):
        return image

    def axis(n_out, n_in):
        x = np.clip((np.arange(n_out) + 0.5) * n_in / n_out - 0.5, 0.0, n_in - 1)
        low = np.floor(x).astype(np.int64)
        high = np.minimum(low + 1, n_in - 1)
        return low, high, (x - low).astype(np.float32)

    y0, y1, fy = axis(height, h)
    x0, x1, fx = axis(width, w)
    shape = (-1, 1) + (1,) * (image.ndim - 2)
    rows = image[y0] * (1.0 - fy.reshape(shape)) + image[y1] * fy.reshape(shape)
    shape = (1, -1) + (1,) * (image.ndim - 2)
    return (rows[:, x0] * (1.0 - fx.reshape(shape)) + rows[:, x1] * fx.reshape(shape)).astype(image.dtype)


# --- The viewport's coarse step -------------------------------------------------------------------

#: The steps of a view render (renderer.render_view_textures): the light passes are built apart.
VIEW_STEPS = ("gbuffer", "direct_light", "vsgl_shading", "vpl_culling", "mrp_asg")
#: The coarse factors the viewport's first coarse image is chosen from (each 0.85 of the last).
COARSE_FACTORS = tuple(float(0.85 ** i) for i in range(19))  # 1 down to 0.054


def view_seconds(plan, settings: VSGLSettings, size: tuple[int, int], full_size: tuple[int, int], model: CostModel,
                 triangles: int = 0, vpl_fraction: float | None = None, vpl_stride: int = 1,
                 guide: bool = True) -> float:
    """Predicted seconds of one view render at ``size`` resolved into ``full_size``: its view steps
    (the VPL pass over one VPL of each ``vpl_stride``, the coarse preview's), the joint bilateral
    resolve at ``full_size`` and, below full size with ``guide`` (the viewport has none kept for this
    view and these triangles), the full-resolution G-buffer that guides the upsampling."""
    features = frame_features(plan, settings, size, size, triangles, vpl_fraction, vpl_stride)
    steps = model.predict_steps({step: features[step] for step in VIEW_STEPS if step in features})
    seconds = sum(steps.values())
    seconds += VIEW_RESOLVE_SECONDS * full_size[0] * full_size[1] / 1e5
    if tuple(size) != tuple(full_size) and guide:
        full = frame_features(plan, settings, full_size, full_size, triangles)["gbuffer"]
        seconds += model.predict({"gbuffer": full})
    return float(seconds)


def coarse_factor(plan, settings: VSGLSettings, full_size: tuple[int, int], scale: float, seconds: float,
                  model: CostModel, triangles: int = 0, vpl_fraction: float | None = None, vpl_stride: int = 1,
                  guide: bool = True) -> tuple[float, float]:
    """(factor, predicted seconds): the largest of COARSE_FACTORS whose view render at ``scale`` ×
    factor of ``full_size`` the model predicts within ``seconds`` (the viewport's step budget), the
    smallest when none is; ``vpl_fraction``, ``vpl_stride``, ``guide`` as for :func:`view_seconds`
    (the stride applies below full size only: at full size the coarse image is a sample)."""
    predicted = math.inf
    for factor in COARSE_FACTORS:
        size = scaled_size(*full_size, scale * factor)  # view_pipeline.view_size's rule
        stride = vpl_stride if tuple(size) != tuple(full_size) else 1
        predicted = view_seconds(plan, settings, size, full_size, model, triangles, vpl_fraction, stride, guide)
        if predicted <= seconds:
            return factor, predicted
    return COARSE_FACTORS[-1], predicted
