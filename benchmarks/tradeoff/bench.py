# SPDX-License-Identifier: GPL-3.0-or-later
"""Our passes on one camera G-buffer, timed with the GPU finished: RSM, VSGL generation, shading."""

from __future__ import annotations

import time

import numpy as np

from gpu_timing import finish, median_seconds

# Rows per uploaded VSGL table: long tables (brute force, random VPLs) are shaded as blended parts.
TABLE_CHUNK = 4096


def chunks(table: dict, size: int = TABLE_CHUNK) -> list[dict]:
    count = len(table["variance"])
    return [{name: value[start:start + size] for name, value in table.items()} for start in range(0, count, size)]


def upload(table: dict):
    """A VSGL table of any length as GPU tables for the shading pass."""
    from vsgl_addon.passes.vsgl_shading import upload_vsgl_table

    return [upload_vsgl_table(part) for part in chunks(table)]


class Bench:
    """One camera G-buffer (and shading inputs) of a scene description, shaded many times."""

    def __init__(self, description, width, height):
        self.materials = [material.name for material in description.materials]
        from vsgl_addon.passes.gbuffer import render_gbuffer
        from vsgl_addon.passes.rsm import SceneGPU
        from vsgl_addon.passes.shading_inputs import shading_gbuffer
        from vsgl_addon.passes.vsgl_shading import VSGLShading

        self.width, self.height = width, height
        self.scene_gpu = SceneGPU(description)
        camera = description.camera
        self.gbuffer = render_gbuffer(self.scene_gpu, camera.view_matrix(), camera.projection_matrix(),
                                      (width, height))
        self.inputs = shading_gbuffer(self.gbuffer)
        arrays = self.gbuffer.to_numpy()
        self.coverage = arrays["position"][..., 3]
        self.material_index = np.rint(arrays["material"][..., 2]).astype(np.int64)
        self.shading = VSGLShading()

    def set_scene(self, description) -> None:
        """Same geometry and camera, other lights (the flicker test's turning spot)."""
        from vsgl_addon.passes.rsm import SceneGPU

        self.scene_gpu.free()
        self.scene_gpu = SceneGPU(description)

    def free(self) -> None:
        self.shading.free()
        self.gbuffer.free()
        self.scene_gpu.free()

    def shade(self, tables, mode=None, repeats=1):
        """(raw diffuse (h, w, 3), raw specular, median seconds) of shading with `tables`, in diffuse
        `mode` (None: the modified kernel's, as the frame shades)."""
        if mode is None:
            from vsgl_addon.reference.vsgl_shading import diffuse_mode_for_kernel

            mode = diffuse_mode_for_kernel("modified")

        def run():
            diffuse, _ = self.shading.run(self.inputs, self.gbuffer.camera_vector, tables, mode)
            finish(diffuse)

        seconds = median_seconds(run, repeats)
        diffuse, specular = self.shading.read()
        return diffuse[..., :3], specular[..., :3], seconds

    def vsgls(self, settings):
        from vsgl_addon.pipeline import render_scene_vsgls

        start = time.perf_counter()
        vsgls = render_scene_vsgls(self.scene_gpu, settings)
        if vsgls.generations:
            finish(vsgls.generations[-1][2].table)
        return vsgls, time.perf_counter() - start

    def rsm(self, size):
        """The RSM views of every light read back (list of RSMArrays) and the GPU time of rendering them."""
        from vsgl_addon.passes.rsm import render_rsm_views

        start = time.perf_counter()
        views = [view for index in range(len(self.scene_gpu.scene.lights))
                 for view in render_rsm_views(self.scene_gpu, index, size)]
        if views:
            finish(views[-1].textures["position"])
        seconds = time.perf_counter() - start
        arrays = [view.to_numpy() for view in views]
        for view in views:
            view.free()
        return arrays, seconds

    def image(self, settings) -> tuple[np.ndarray, bool]:
        """Diffuse + specular indirect (float64) of `settings`' VSGLs, and whether it is finite."""
        from vsgl_addon.reference.vsgl_shading import diffuse_mode_for_kernel

        vsgls, _ = self.vsgls(settings)
        d, s, _ = self.shade(vsgls.tables(), diffuse_mode_for_kernel(settings.kernel))
        vsgls.free()
        return (d + s).astype(np.float64), bool(np.all(np.isfinite(d)) and np.all(np.isfinite(s)))
