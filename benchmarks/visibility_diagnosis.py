# SPDX-License-Identifier: GPL-3.0-or-later
"""Where VSGL visibility's error comes from (not a test): imperfect shadow maps against exact
visibility, per scene of the validation suite.

    .venv/bin/python benchmarks/visibility_diagnosis.py [--only NAME ...] [--stride S] [--material NAME]

On every S-th pixel (both ways) of the suite's 240x180 camera G-buffer, each VSGL lobe's light is
computed by the float64 reference shading (reference/vsgl_shading.shade, per term) and weighted by
three visibilities:

* none (visibility off);
* the GPU's imperfect shadow maps, read back and looked up by the float64 twin
  (reference/vsgl_shading.vsgl_visibility: the shader's lookup, tested bit-close to it);
* exact: the segment from the receiver to the map's shadow origin ray-cast against every triangle
  of the scene (brute force), hits nearer the origin than the own-reflector radius left out as the
  maps leave those points out; and the bare segment to the VSGL's mean (no push, nothing left out).

Their means over the pixels, against Cycles' on the same pixels, separate the maps' error (ISM
against exact) from the VSGL model's (exact against Cycles: positions as Gaussians' means, the
diffuse approximation). Prints one line per scene and configuration. ``--material``: only the
pixels of that material (e.g. "Glossy tiles", sun_courtyard's north wall, whose courtyard face is
in the sun's shadow).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
for folder in (REPO, REPO / "tests", REPO / "benchmarks", REPO / "tools"):
    sys.path.insert(0, str(folder))

from validation_suite import scene_with_truth, suite  # noqa: E402
from build_validation_scenes import RESOLUTION  # noqa: E402
from tradeoff.bench import Bench  # noqa: E402
from tradeoff.demo import COVERED, log  # noqa: E402

LUMINANCE = np.array([0.2126, 0.7152, 0.0722])


def segment_visible(receivers, origin, triangles, exclude_radius, receiver_offset=1e-3):
    """(P,) 1 where no triangle crosses the segment from each receiver to ``origin`` (Möller–Trumbore),
    hits within ``exclude_radius`` of the origin and within ``receiver_offset`` of the receiver left out."""
    o = receivers
    d = origin[None, :] - o
    length = np.linalg.norm(d, axis=-1)
    visible = np.ones(len(o), bool)
    v0, e1, e2 = triangles[:, 0], triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0]
    t_min = receiver_offset / np.maximum(length, 1e-30)
    t_max = 1.0 - exclude_radius / np.maximum(length, 1e-30)
    for start in range(0, len(v0), 256):
        a0, a1, a2 = v0[start:start + 256], e1[start:start + 256], e2[start:start + 256]
        p = np.cross(d[:, None, :], a2[None])  # (P, T, 3)
        det = np.einsum("ptk,tk->pt", p, a1)
        inv = 1.0 / np.where(np.abs(det) > 1e-14, det, np.inf)
        s = o[:, None, :] - a0[None]
        u = np.einsum("ptk,ptk->pt", s, p) * inv
        q = np.cross(s, a1[None])
        v = np.einsum("pk,ptk->pt", d, q) * inv
        t = np.einsum("ptk,tk->pt", q, a2) * inv
        hit = (u >= 0) & (v >= 0) & (u + v <= 1) & (t > t_min[:, None]) & (t < t_max[:, None])
        visible &= ~hit.any(axis=1)
    return visible.astype(np.float64)


def exact_visibility(table, maps_per_vsgl, position, triangles, exclude_sigmas, pushed=True):
    """(P, N, 2) exact visibility of each lobe's shadow origin (reference.ism.shadow_origin of the
    position the maps use: the VSGL's diffuse lobe's with one map per VSGL, else the lobe's), or of
    that position itself (``pushed=False``)."""
    from vsgl_addon.reference.ism import shadow_origin

    count = len(table["diffuse_variance"])
    result = np.ones((len(position), count, 2))
    for lobe, name in enumerate(("diffuse", "specular")):
        at = "diffuse_" if maps_per_vsgl == 1 else f"{name}_"
        means = table[f"{at}mean"]
        if pushed:
            means = shadow_origin(means, table[f"{at}variance"], table[f"{name}_axis"])
        sigma = np.sqrt(np.maximum(table[f"{at}variance"], 0.0))
        for i in range(count):
            if lobe == 1 and maps_per_vsgl == 1:
                result[:, i, 1] = result[:, i, 0]
                continue
            result[:, i, lobe] = segment_visible(position, np.asarray(means[i], np.float64), triangles,
                                                 exclude_sigmas * sigma[i])
    return result


def diagnose(name, path, stride, settings_overrides, material=None):
    from vsgl_addon.passes.gpu_util import read_texture
    from vsgl_addon.pipeline import build_visibility
    from vsgl_addon.reference.vsgl_shading import diffuse_mode_for_kernel, shade, vsgl_visibility
    from vsgl_addon.passes.vsgl_shading import ISM_MAX_RADIUS

    width, height = RESOLUTION
    saved, truth, description = scene_with_truth(name, path, width, height)
    settings = saved.overridden(visibility=True, **settings_overrides)
    triangles = np.asarray(description.geometry.positions, np.float64)
    bench = Bench(description, width, height)
    try:
        arrays = bench.gbuffer.to_numpy()
        rd = read_texture(bench.inputs.diffuse_reflectance, width, height)[..., :3]
        f0 = read_texture(bench.inputs.specular_f0, width, height)[..., :3]
        pick = np.zeros((height, width), bool)
        pick[stride // 2::stride, stride // 2::stride] = True
        pick &= (arrays["position"][..., 3] > COVERED) & (truth["alpha"] > COVERED)
        if material is not None:
            pick &= bench.material_index == bench.materials.index(material)
        position = arrays["position"][..., :3][pick].astype(np.float64)
        normal = arrays["normal"][..., :3][pick].astype(np.float64)
        normal /= np.maximum(np.linalg.norm(normal, axis=-1, keepdims=True), 1e-30)
        roughness = arrays["normal"][..., 3][pick].astype(np.float64) ** 2
        camera = np.asarray(bench.gbuffer.camera_vector, np.float64).reshape(-1)
        view = camera[:3] - position if camera.shape[0] == 3 or camera[3] > 0 else np.broadcast_to(camera[:3], position.shape)
        view = view / np.linalg.norm(view, axis=-1, keepdims=True)
        vsgls, _ = bench.vsgls(settings)
        try:
            build_visibility(bench.scene_gpu, vsgls, settings)
            sums = {"off": 0.0, "ism": 0.0, "exact": 0.0, "exact_mean0": 0.0}
            over = under = 0.0
            for table, atlas in zip(vsgls.table_arrays(), vsgls.isms):
                table = {k: np.asarray(v, np.float64) for k, v in table.items()}
                maps = atlas.count // len(table["variance"])
                _, _, terms = shade(table, position, normal, view, rd[pick], f0[pick], roughness,
                                    diffuse_mode=diffuse_mode_for_kernel(settings.kernel), per_term=True)
                weight = (terms.sum(axis=3) @ LUMINANCE)  # (P, N, 2)
                v_ism = vsgl_visibility(atlas.read(), maps, table, position, normal, ISM_MAX_RADIUS)
                v_exact = exact_visibility(table, maps, position, triangles, 1.0)
                v_exact0 = exact_visibility(table, maps, position, triangles, 0.0, pushed=False)
                sums["off"] += weight.sum()
                sums["ism"] += (weight * v_ism).sum()
                sums["exact"] += (weight * v_exact).sum()
                sums["exact_mean0"] += (weight * v_exact0).sum()
                over += (weight * np.maximum(v_exact - v_ism, 0)).sum()
                under += (weight * np.maximum(v_ism - v_exact, 0)).sum()
        finally:
            vsgls.free()
    finally:
        bench.free()
    cycles = float((truth["indirect"][pick] @ LUMINANCE).sum())
    line = (f"{name}{'' if material is None else f' ({material})'} {settings_overrides}: pixels {pick.sum()}, ours/Cycles off {sums['off'] / cycles:.3f}, "
            f"ISM {sums['ism'] / cycles:.3f}, exact (shadow origin, 1 sigma excluded) {sums['exact'] / cycles:.3f}, "
            f"exact (bare segment to the mean) {sums['exact_mean0'] / cycles:.3f}; ISM over-shadows "
            f"{over / sums['off']:.3f} and leaks {under / sums['off']:.3f} of the unshadowed light")
    log(line)
    return sums, cycles


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", nargs="+", default=["occluder", "cornell_box", "closed_room"])
    parser.add_argument("--stride", type=int, default=6)
    parser.add_argument("--vsgl-count", type=int, default=None)
    parser.add_argument("--ism-points", type=int, default=None)
    parser.add_argument("--material", default=None, help="only the pixels of this material")
    args = parser.parse_args(argv)
    from vsgl_addon import register

    register()
    from vsgl_addon.gpu_context import ensure_gpu_context

    ensure_gpu_context()
    overrides = {name: value for name, value in (("vsgl_count", args.vsgl_count), ("ism_points", args.ism_points))
                 if value is not None}
    for name, path, _ in suite():
        if name in args.only:
            start = time.perf_counter()
            diagnose(name, path, args.stride, overrides, args.material)
            log(f"  ({time.perf_counter() - start:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
