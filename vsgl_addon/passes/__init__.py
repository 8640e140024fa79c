# SPDX-License-Identifier: GPL-3.0-or-later
"""GPU passes, one module per pass. A pass takes plain numpy data or GPU textures and never
touches ``bpy.context``; its float64 twin lives in ``vsgl_addon.reference``.

* :mod:`.vsgl_generation`: VSGLs from a reflective shadow map (000 §3-4, app. B and D; 003).

Shared by the passes (not passes themselves): :mod:`.scene_gpu` (the scene's triangles on the GPU,
their vertex stage and per-material inputs, drawn by :mod:`.rsm` and :mod:`.gbuffer`) and
:mod:`.gpu_util` (numpy arrays to and from textures, matrices for uniforms).
"""
