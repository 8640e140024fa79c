# SPDX-License-Identifier: GPL-3.0-or-later
"""GPU passes, one module per pass. A pass takes plain numpy data or GPU textures and never
touches ``bpy.context``; its float64 twin lives in ``vsgl_addon.reference``.

* :mod:`.rsm`: reflective shadow maps of every light (000 §4; formulas.md §4).
* :mod:`.brsm`: the view-dependent PDF of VSGL generation (000 §5, bidirectional RSMs).
* :mod:`.vsgl_generation`: VSGLs from a reflective shadow map (000 §3-4, app. B and D; 003).
* :mod:`.ism`: imperfect shadow maps of the VSGLs, for their visibility (000 §5).
* :mod:`.gbuffer`: the camera G-buffer.
* :mod:`.direct_light`: direct light with RSM-depth shadows.
* :mod:`.shading_inputs`: the G-buffer's Principled inputs -> Rd and F0 for VSGL shading.
* :mod:`.vsgl_shading`: indirect light from VSGLs (000 app. C).
* :mod:`.vpl_culling`: glossy VPLs with stochastic light culling, caustics on diffuse receivers (004).
* :mod:`.mrp_visibility`: mirror shadow maps of the rectangle proxies (MRP-ASG's proxy-to-receiver visibility).
* :mod:`.mrp_asg`: glossy interreflection from rectangle proxies (001).

Each pass module declares its contract once, as ``PASS`` (:class:`.contract.GPUPass`: shaders,
layouts read and written, timed step, ``run`` entry); :data:`PASSES` lists them in frame order and
is the one place warm-up, the timed steps and the statistics labels come from, so a new pass is one
module and one entry here for all of them.

Shared by the passes (not passes themselves): :mod:`.contract` (the pass contract),
:mod:`.scene_gpu` (the scene's triangles on the GPU, their vertex stage and per-material inputs,
drawn by :mod:`.rsm` and :mod:`.gbuffer`) and :mod:`.gpu_util` (numpy arrays to and from textures,
matrices for uniforms). The texture layouts passes hand each other: :mod:`vsgl_addon.layouts`.
"""

import atexit

from . import (brsm, direct_light, gbuffer, ism, mrp_asg, mrp_visibility, rsm, shading_inputs, vpl_culling, vsgl_generation,
               vsgl_shading)
from .contract import GPUPass, Step

#: Every GPU pass, in the order a frame runs them.
PASSES: tuple[GPUPass, ...] = (rsm.PASS, brsm.PASS, vsgl_generation.PASS, ism.PASS, mrp_visibility.PASS, gbuffer.PASS,
                               direct_light.PASS, shading_inputs.PASS, vsgl_shading.PASS, vpl_culling.PASS,
                               mrp_asg.PASS)

#: Steps of a frame that are not GPU passes. Scene extraction is the Blender-facing caller's (the
#: engine and the overlay time it); upload and read-back are the renderer's.
SCENE_EXTRACTION = Step("scene_extraction", "Scene Extraction")
UPLOAD = Step("upload", "Upload", {"lights": "Lights", "triangles": "Triangles"})
READ_BACK = Step("read_back", "Read Back")
#: The glossy VPLs read from the RSM once per scene state, after the light passes and their maps.
VPL_EXTRACTION = vpl_culling.EXTRACTION


def _steps() -> tuple[Step, ...]:
    steps = [SCENE_EXTRACTION, UPLOAD]
    for gpu_pass in PASSES:
        if gpu_pass.step not in steps:
            steps.append(gpu_pass.step)
        if gpu_pass is ism.PASS:
            steps.append(VPL_EXTRACTION)
    return tuple(steps + [READ_BACK])


#: Every timed step of a frame, in order: the keys of ``FrameImages.timings``.
STEPS: tuple[Step, ...] = _steps()
#: Timing key -> label, and count key -> label, for the statistics panel and reports.
TIMING_LABELS = {step.name: step.label for step in STEPS}
COUNT_LABELS = {key: label for step in STEPS for key, label in step.counts.items()}


def compile_all_shaders() -> None:
    """Compile every pass's shaders now (each is cached for the process): a warm-up before the first
    frame, and the check that every stage compiles on this Blender's GLSL front end."""
    for gpu_pass in PASSES:
        gpu_pass.compile_shaders()


def free_all_shaders() -> None:
    """Drop every pass's cached shaders (and what was made from them)."""
    for gpu_pass in PASSES:
        gpu_pass.free_shaders()


# The cached shaders and batches must go while Blender's GPU backend is alive: at interpreter exit
# the bpy module shuts it down in its own atexit handler, and a GPU object collected after that
# crashes the process (a segmentation fault after the work is done). atexit runs handlers last in,
# first out, and this module is always imported after bpy.
atexit.register(free_all_shaders)
