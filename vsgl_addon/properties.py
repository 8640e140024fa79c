# SPDX-License-Identifier: GPL-3.0-or-later
"""The add-on's render parameters, stored per scene as ``scene.vsgl`` (Blender-facing only, no pass logic).

Paper references: 000 = Tokuyoshi, "Modified filtered importance sampling for virtual spherical
Gaussian lights" (CVM 2016); 003 = the Square Enix spherical Gaussian talk (2015).
See /work/shared/reference/formulas.md, sections 4-5.
"""

import bpy
from bpy.props import EnumProperty, FloatProperty, IntProperty, PointerProperty
from bpy.types import PropertyGroup

from .settings import K_RANGE, RSM_SIZE_RANGE, VSGL_COUNT_RANGE

# Identifiers are stored in .blend files: rename the labels freely, never the identifiers.
KERNEL_ITEMS = (
    (
        "MODIFIED",
        "Modified (Eq. 3)",
        "The paper's method (000 Eqs. 3, 5): each VSGL's kernel size is found by bisection on the "
        "mipmapped PDF, so a cluster's light and its PDF are filtered by the same kernel. "
        "Temporally stable; costs the same as Original within a few percent",
        0,
    ),
    (
        "ORIGINAL",
        "Original (Eqs. 1, 4)",
        "Classic filtered importance sampling (Krivanek-Colbert, Tokuyoshi 2015): kernel size from "
        "the PDF at the kernel centre only. Kept for comparison: kernels overlap or leave gaps, "
        "which shows as flickering and errors with a changing, high-frequency PDF",
        1,
    ),
    (
        "TWO_VSGL",
        "Two VSGLs (003)",
        "Simplified mode for a spot light on a local region (003): one diffuse and one specular VSGL "
        "summed over the whole reflective shadow map, with no mipmap and no sampling. Cheapest and "
        "flicker-free, but all bounce light comes from one blurred source; ignores VSGL Count and K",
        2,
    ),
)


class VSGLSceneSettings(PropertyGroup):
    """VSGL render parameters of a scene (``scene.vsgl``)."""

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
        items=KERNEL_ITEMS,
        default="MODIFIED",
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


CLASSES = (VSGLSceneSettings,)


def _scene_settings_property():
    return PointerProperty(
        type=VSGLSceneSettings,
        name="VSGL",
        description="VSGL indirect light settings of this scene",
    )


# (owner type, attribute name, factory of the property), attached by vsgl_addon.register().
TYPE_PROPERTIES = ((bpy.types.Scene, "vsgl", _scene_settings_property),)
