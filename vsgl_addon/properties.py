# SPDX-License-Identifier: GPL-3.0-or-later
"""The add-on's render parameters, stored per scene as ``scene.vsgl`` (Blender-facing only, no pass logic).

Paper references: 000 = Tokuyoshi, "Modified filtered importance sampling for virtual spherical
Gaussian lights" (CVM 2016); 003 = the Square Enix spherical Gaussian talk (2015).
See /work/shared/reference/formulas.md, sections 4-5.
"""

import math

import bpy
from bpy.props import BoolProperty, EnumProperty, FloatProperty, IntProperty, PointerProperty
from bpy.types import PropertyGroup

from . import overlay
from .settings import (CAUSTIC_ROUGHNESS_RANGE, DELTA_RANGE, DISK_RADIUS_RANGE, INTERLEAVE_CHOICES, ISM_POINTS_RANGE,
                       ISM_SIZE_RANGE, K_RANGE, KERNELS, OVERLAY_DISPLAYS, PDFS, POSITIONS, PROXY_OVERRIDES,
                       QUALITY_MODES, REFLECTOR_MODES, RSM_SIZE_RANGE, TIME_BUDGET_RANGE, VIEWPORT_PASSES,
                       VPL_FILTER_RADIUS_RANGE, VPL_SAMPLES_RANGE, VSGL_COUNT_RANGE)


def enum_items(choices) -> tuple[tuple[str, str, str, int], ...]:
    """EnumProperty items of a settings.Choices table. The number is the row's position: Blender
    stores it in the .blend, which is why rows are only appended."""
    return tuple((choice.identifier, choice.label, choice.description, number)
                 for number, choice in enumerate(choices))


def _overlay_changed(settings, context):
    """Overlay switched on or off: free its GPU resources or start updating (overlay.py)."""
    overlay.on_overlay_toggled(bool(settings.show_overlay))


def _proxy_outlines_changed(settings, context):
    """Proxy outlines switched on or off (proxy_outlines.py)."""
    from . import proxy_outlines

    proxy_outlines.on_toggled(bool(settings.show_proxy_outlines))


class VSGLSceneSettings(PropertyGroup):
    """VSGL render parameters of a scene (``scene.vsgl``)."""

    quality_mode: EnumProperty(
        name="Quality",
        description="Set the frame's quality by hand, or ask for a frame time and let a cost model of this "
                    "machine choose VSGL count, RSM resolution, delta, VPL interleave and resolution, or let the "
                    "planner leave out the VPL pass or MRP-ASG where it costs much for little of the light (Auto)",
        items=enum_items(QUALITY_MODES),
        default="MANUAL",
    )
    time_budget_ms: FloatProperty(
        name="Target Frame Time",
        description=(
            "Budget mode: the frame time to aim for, in milliseconds (the sum of the passes' times). A "
            "smaller target gives fewer VSGLs, smaller RSMs, a larger delta and interleave and, last, a "
            "lower resolution (upscaled); the first budgeted render calibrates the cost model (a few "
            "frames). The statistics show the predicted and the measured time"
        ),
        default=100.0,
        min=TIME_BUDGET_RANGE[0],
        max=TIME_BUDGET_RANGE[1],
        soft_max=10000.0,
        precision=0,
    )
    vsgl_count: IntProperty(
        name="VSGL Count",
        description=(
            "Number N of virtual spherical Gaussian lights the reflective shadow map is clustered "
            "into (000 section 4). Shading time grows in proportion to N, since every pixel "
            "evaluates every VSGL; more VSGLs keep more detail of the indirect light and undo the "
            "blur a larger K adds"
        ),
        default=256,
        min=VSGL_COUNT_RANGE[0],
        max=VSGL_COUNT_RANGE[1],
    )
    k: FloatProperty(
        name="K",
        description=(
            "Kernel size factor K of filtered importance sampling (000 Eq. 3 uses K/N instead of "
            "1/N): each VSGL gathers about K/N of the light. Larger K blurs the indirect light "
            "more and flickers less over time; it costs almost nothing. 1 is the paper's setting"
        ),
        default=1.0,
        min=K_RANGE[0],
        max=K_RANGE[1],
        soft_max=8.0,
        step=25,
        precision=2,
    )
    kernel: EnumProperty(
        name="Kernel",
        description="How the reflective shadow map is clustered into VSGLs",
        items=enum_items(KERNELS),
        default="MODIFIED",
    )
    pdf: EnumProperty(
        name="PDF",
        description="Where VSGL generation places its kernels: by the light's bounce power, or by what the "
                    "camera sees of it too (000 §5)",
        items=enum_items(PDFS),
        default="VIEW",
    )
    positional_distribution: EnumProperty(
        name="Lobe Positions",
        description="Where each VSGL's diffuse and specular light come from",
        items=enum_items(POSITIONS),
        default="PER_LOBE",
    )
    rsm_size: IntProperty(
        name="RSM Resolution",
        description=(
            "Width and height in texels of the reflective shadow map rendered for each light; "
            "every texel is a virtual point light. Time and memory grow with its square; more "
            "texels resolve smaller and thinner reflectors. The paper uses 512 (000 section 5); "
            "64 to 128 is enough for the Two VSGLs mode (003). VSGL generation walks a square mip "
            "chain, so the nearest power of two is used"
        ),
        default=128,
        min=RSM_SIZE_RANGE[0],
        max=RSM_SIZE_RANGE[1],
        soft_min=16,
        soft_max=1024,
        subtype="PIXEL",
    )
    visibility: BoolProperty(
        name="VSGL Visibility",
        description=(
            "Shadow the bounce light: each VSGL gets an imperfect shadow map (000 section 5), so "
            "indirect light stops leaking through walls and objects cast indirect shadows (half "
            "the error where an occluder stands between bounce and receiver). Costs a point splat "
            "per VSGL and a filtered lookup per pixel and VSGL: on a CPU renderer about 2.5x the "
            "shading time, plus 0.1-0.3 s of shadow maps at N = 256; off, every VSGL lights "
            "every surface it faces"
        ),
        default=True,
    )
    ism_size: IntProperty(
        name="Shadow Map Resolution",
        description=(
            "Width and height in texels of each VSGL's imperfect shadow map (an octahedral map "
            "of all directions; the paper uses 64). Larger maps give sharper indirect shadows but "
            "need more points to stay hole-free; the nearest power of two is used"
        ),
        default=64,
        min=ISM_SIZE_RANGE[0],
        max=ISM_SIZE_RANGE[1],
        subtype="PIXEL",
    )
    ism_points: IntProperty(
        name="Points per Shadow Map",
        description=(
            "Scene surface points splatted into each VSGL's shadow map (Ritschel et al. 2008). "
            "Time grows with points x VSGLs; too few leave holes that thin occluders leak "
            "through (pull-push fills small ones). About the map's texel count is a good start"
        ),
        default=4096,
        min=ISM_POINTS_RANGE[0],
        max=ISM_POINTS_RANGE[1],
    )
    # --- glossy reflectors (001, MRP-ASG) ---
    glossy_reflectors: BoolProperty(
        name="Glossy Reflectors",
        description=(
            "Render the light that sharp planar glossy reflectors (polished floors, table tops, panels) "
            "reflect onto glossy surfaces with MRP-ASG (001): each such region becomes a rectangle proxy, "
            "and its reflected light comes straight from the lights at the specular peak instead of "
            "from the VSGLs, which blur it. Costs one full-screen draw per light that reaches a proxy; "
            "a scene without proxies pays nothing"
        ),
        default=True,
    )
    disk_radius: FloatProperty(
        name="Disk Radius",
        description=(
            "Smallest radius r_d of the sampling disk at each specular peak (001 section 3.4), in "
            "metres: the part of the reflector whose light a receiver gathers. The disk is never "
            "smaller than 1.5 footprints of the reflector's highlight seen from the receiver, so a "
            "small r_d loses no light; a larger one spreads the light over the disk, blurring sharp "
            "reflections. It costs nothing either way"
        ),
        default=0.1,
        min=DISK_RADIUS_RANGE[0],
        max=DISK_RADIUS_RANGE[1],
        soft_min=0.005,
        soft_max=2.0,
        subtype="DISTANCE",
        unit="LENGTH",
        precision=3,
    )
    caustic_roughness: FloatProperty(
        name="Sharp Below",
        description=(
            "Caustic roughness alpha_c: a surface whose GGX alpha (roughness squared) is below it counts "
            "as a sharp glossy reflector. Its planar regions become rectangle proxies (per object: Object "
            "Properties > VSGL Glossy Reflector), and its light on matte surfaces is rendered by the "
            "glossy VPLs (Caustics). Higher hands rougher surfaces to them too, where MRP-ASG's fit is "
            "less accurate and the VPLs cost more"
        ),
        default=0.1,
        min=CAUSTIC_ROUGHNESS_RANGE[0],
        max=CAUSTIC_ROUGHNESS_RANGE[1],
        precision=3,
    )
    reflector_mode: EnumProperty(
        name="Reflector Shading",
        description="How a receiver is shaded with a proxy's reflected light",
        items=enum_items(REFLECTOR_MODES),
        default="ASG",
    )
    # --- glossy VPLs (004, stochastic light culling) ---
    caustics: BoolProperty(
        name="Caustics",
        description=(
            "Render the light sharp glossy reflectors (GGX alpha below Sharp Below) throw onto matte "
            "surfaces with glossy VPLs and stochastic light culling (004): every reflective shadow map "
            "texel of such a reflector is a VPL, so the caustic stays small and sharp instead of the "
            "VSGLs' blurred blob. Runs only where such a lit reflector exists; elsewhere it costs nothing"
        ),
        default=True,
    )
    # δ spans five decades (004 §3.1), so the control is its base-10 logarithm: a slider's step is
    # then the same factor anywhere in the range.
    delta_log10: FloatProperty(
        name="Delta (log10)",
        description=(
            "Base-10 logarithm of the acceptance threshold delta of stochastic light culling (004 Eq. 2; "
            "-3 is 004's 0.001): a VPL lights a pixel with probability min(I / (delta l^2), 1), its light "
            "divided by that probability (unbiased). Larger delta: shorter light ranges, fewer VPLs per "
            "pixel, faster but noisier. Smaller: slower, less noise"
        ),
        default=-3.0,
        min=math.log10(DELTA_RANGE[0]),
        max=math.log10(DELTA_RANGE[1]),
        precision=2,
    )
    vpl_interleave: EnumProperty(
        name="Interleave",
        description=(
            "Interleaved sampling N x N (004 section 6): each pixel of an N x N block shades a different "
            "N^2-th of the culled VPLs, so shading costs 1/N^2; the filter removes the pattern. Larger: "
            "faster, noisier"
        ),
        items=enum_items(INTERLEAVE_CHOICES),
        default="AUTO",
    )
    vpl_filter_radius: IntProperty(
        name="Filter Radius",
        description=(
            "Radius in pixels of the cross-bilateral filter (guided by depth and normal) that removes "
            "the interleaving pattern and the culling noise (004 uses 8). Larger: smoother, blurs the "
            "caustic's edge more; 0: no filter"
        ),
        default=8,
        min=VPL_FILTER_RADIUS_RANGE[0],
        max=VPL_FILTER_RADIUS_RANGE[1],
        subtype="PIXEL",
    )
    vpl_samples: IntProperty(
        name="VPL Samples",
        description=(
            "Independent culling draws averaged per image: noise falls as 1 / sqrt(S) towards the "
            "unbiased result, time grows with S. Raise it for final renders"
        ),
        default=1,
        min=VPL_SAMPLES_RANGE[0],
        max=VPL_SAMPLES_RANGE[1],
    )
    vpl_visibility: BoolProperty(
        name="VPL Shadows",
        description=(
            "Shadow the VPLs' light (with VSGL Visibility on): one imperfect shadow map per cluster of "
            "VPLs (16x16 RSM texels). Removes the light an occluder blocks, so caustics do not leak "
            "through walls; costs one small map per cluster and reading the VPLs back to the CPU"
        ),
        default=True,
    )
    seed: IntProperty(
        name="Seed",
        description=(
            "Seed of the sample patterns (VSGL kernel centres, stochastic choices). Another seed "
            "moves the noise and clustering pattern without changing the expected image; keep it "
            "fixed for renders that must repeat exactly"
        ),
        default=0,
        min=0,
    )

    # --- viewport overlay (overlay.py); none of these changes a render ---
    show_overlay: BoolProperty(
        name="Overlay",
        description=(
            "Show the VSGL indirect light over every 3D viewport, for the viewport's own view. "
            "While on, every scene change reruns the light passes (reflective shadow maps and "
            "VSGL generation) and every view change reruns the viewport shading, a coarse image "
            "first, then a refined one once nothing moves. Off frees all its GPU memory. Hidden "
            "in a viewport whose Show Overlays is off"
        ),
        default=False,
        update=_overlay_changed,
    )
    overlay_mode: EnumProperty(
        name="Display",
        description="What the overlay shows; switching costs nothing (every pass is kept)",
        items=enum_items(OVERLAY_DISPLAYS),
        default="INDIRECT",
    )
    overlay_resolution_scale: FloatProperty(
        name="Resolution",
        description=(
            "Resolution of the overlay's first, coarse image after a change, as a fraction of the "
            "viewport's pixels per side; it is upsampled to the viewport guided by its depth and "
            "normals, so edges stay sharp, and later samples are at full resolution. Its shading "
            "time grows with the square of this: 0.5 costs 4 times 0.25. Lower answers a change "
            "sooner; higher shows a sharper first image"
        ),
        default=0.25,
        min=0.02,
        max=1.0,
        soft_min=0.05,
        subtype="FACTOR",
        precision=2,
    )
    overlay_intensity: FloatProperty(
        name="Intensity",
        description=(
            "Multiplier of the overlay's brightness (display only: renders are unchanged). Raise "
            "it to see faint bounce light, lower it when bright glossy reflections saturate; "
            "the scene's exposure applies on top"
        ),
        default=1.0,
        min=0.0,
        max=1000.0,
        soft_max=16.0,
        precision=2,
    )

    show_proxy_outlines: BoolProperty(
        name="Proxy Outlines",
        description=(
            "Draw the outlines of the rectangle proxies MRP-ASG uses (debug view, every 3D viewport): "
            "orange where a light reaches the proxy, with a blue tick along each lit side's normal; "
            "grey where none does (built, not shaded). Rebuilt when geometry, materials or lights "
            "change; changes no render"
        ),
        default=False,
        update=_proxy_outlines_changed,
    )

    # --- the Rendered viewport (engine.py view_draw) ---
    viewport_resolution_scale: FloatProperty(
        name="Preview Resolution",
        description=(
            "Resolution of the first, coarse image after a change in Rendered shading, as a fraction "
            "of the viewport's pixels per side; it is upsampled to the viewport guided by its depth and "
            "normals, so edges stay sharp. Later samples are at full resolution"
        ),
        default=0.25,
        min=0.05,
        max=1.0,
        subtype="FACTOR",
        precision=2,
    )
    viewport_samples: IntProperty(
        name="Viewport Samples",
        description=(
            "Full-resolution samples averaged in Rendered shading and in the overlay while nothing "
            "changes, each with a new rotation of the VSGL lattice; the image converges to the "
            "techniques' expected value. More samples: a smoother image, longer refinement"
        ),
        default=16,
        min=1,
        max=4096,
    )
    viewport_pass: EnumProperty(
        name="Viewport Pass",
        description="Which light Rendered shading shows (the render passes F12 writes)",
        items=enum_items(VIEWPORT_PASSES),
        default="COMBINED",
    )


CLASSES = (VSGLSceneSettings,)


def _object_proxy_property():
    return EnumProperty(
        name="Glossy Reflector",
        description="Whether this object's planar regions become rectangle proxies for MRP-ASG (001)",
        items=enum_items(PROXY_OVERRIDES),
        default="AUTO",
    )


def _scene_settings_property():
    return PointerProperty(
        type=VSGLSceneSettings,
        name="VSGL",
        description="VSGL indirect light settings of this scene",
    )


# (owner type, attribute name, factory of the property), attached by vsgl_addon.register().
TYPE_PROPERTIES = ((bpy.types.Scene, "vsgl", _scene_settings_property),
                   (bpy.types.Object, "vsgl_proxy", _object_proxy_property))
