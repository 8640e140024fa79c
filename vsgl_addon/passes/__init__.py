# SPDX-License-Identifier: GPL-3.0-or-later
"""GPU passes, one module per pass. A pass takes plain numpy data or GPU textures and never
touches ``bpy.context``; its float64 twin lives in ``vsgl_addon.reference``.

* :mod:`.rsm`: reflective shadow maps of every light (000 §4; formulas.md §4).
* :mod:`.vsgl_generation`: VSGLs from a reflective shadow map (000 §3-4, app. B and D; 003).
* :mod:`.gbuffer`: the camera G-buffer.
* :mod:`.direct_light`: direct light with RSM-depth shadows.
* :mod:`.shading_inputs`: the G-buffer's Principled inputs -> Rd and F0 for VSGL shading.
* :mod:`.vsgl_shading`: indirect light from VSGLs (000 app. C).

Shared by the passes (not passes themselves): :mod:`.scene_gpu` (the scene's triangles on the GPU,
their vertex stage and per-material inputs, drawn by :mod:`.rsm` and :mod:`.gbuffer`) and
:mod:`.gpu_util` (numpy arrays to and from textures, matrices for uniforms).
"""


def _modules():
    from . import direct_light, gbuffer, rsm, shading_inputs, vsgl_generation, vsgl_shading

    return rsm, vsgl_generation, gbuffer, direct_light, shading_inputs, vsgl_shading


def compile_all_shaders() -> None:
    """Compile every pass's shaders now (each is cached for the process): a warm-up before the first
    frame, and the check that every stage compiles on this Blender's GLSL front end."""
    rsm, vsgl_generation, gbuffer, direct_light, shading_inputs, vsgl_shading = _modules()
    for module in (rsm, gbuffer, direct_light, shading_inputs):
        module.shader()
    vsgl_generation.compile_shaders()
    vsgl_shading.compile_shaders()


def free_all_shaders() -> None:
    """Drop every pass's cached shaders (and the batches made for them)."""
    for module in _modules():
        module.free_shaders()
