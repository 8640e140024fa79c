# SPDX-License-Identifier: GPL-3.0-or-later
"""The view-dependent PDF of VSGL generation on the GPU (000 §5, bidirectional reflective shadow
maps): the twin of :mod:`vsgl_addon.reference.brsm` through ``glsl/lib/brsm.glsl``. Per RSM view,
three compute stages (``glsl/brsm/``), nothing read back:

1. ``view_pdf_terms.comp.glsl``: per texel, the light PDF's weight w and w I, I the unshadowed
   diffuse form factor with the view's receivers (reference ``view_importance``);
2. ``view_pdf_sums.comp.glsl``: their sums over the RSM, one work group;
3. ``view_pdf.comp.glsl``: the defensive mixture p per texel (reference ``view_pdf``), in the R
   channel of the PDF image VSGL generation reads (``vsgl_generation.upload_pdf``'s layout).

    receivers = upload_receivers(pipeline.view_receivers(...))   # once per frame
    pdf = run(view.rsm_textures(), receivers)                     # per RSM view: a texture
    receivers.free()

The receivers come from the camera's small G-buffer (``pipeline.view_receivers``, read back once
per frame); the texels × receivers sum, which the float64 reference pays per view on the CPU, runs
here. Needs a GPU context, main thread.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..layouts import RSM
from ..reference import brsm as _reference
from ..shaders import ShaderInterface
from .contract import LIGHT_PASSES, GPUPass, ShaderSpec
from .gpu_util import set_uniform, texture_from_array

#: Invocations of the sums' one work group.
SUM_GROUP = 256
_TEXEL_GROUP = (8, 8, 1)
_TERMS = ("RGBA32F", "FLOAT_2D", "view_pdf_terms")
_PUSH = [("INT", "rsm_size"), ("IVEC4", "view_pdf_sizes"), ("VEC4", "view_pdf_params")]


def _rsm_samplers() -> list[tuple[str, str]]:
    return [("FLOAT_2D", f"rsm_{name}") for name in RSM.slot_names]


def _terms_interface() -> ShaderInterface:
    return ShaderInterface(push_constants=_PUSH, samplers=_rsm_samplers() + [("FLOAT_2D", "view_receivers")],
                           images=[_TERMS], local_group_size=_TEXEL_GROUP)


def _sums_interface() -> ShaderInterface:
    return ShaderInterface(push_constants=[("INT", "rsm_size")],
                           images=[_TERMS, ("RGBA32F", "FLOAT_2D", "view_pdf_sums")],
                           local_group_size=(SUM_GROUP, 1, 1),
                           shared=f"shared vec2 view_pdf_partial[{SUM_GROUP}];")


def _mixture_interface() -> ShaderInterface:
    return ShaderInterface(push_constants=_PUSH, samplers=[("FLOAT_2D", "view_receivers")],
                           images=[_TERMS, ("RGBA32F", "FLOAT_2D", "view_pdf_sums"),
                                   ("RGBA32F", "FLOAT_2D", "view_pdf_image")],
                           local_group_size=_TEXEL_GROUP)


@dataclass
class ViewReceivers:
    """The view PDF's receivers on the GPU: a (max(count, 1), 2) RGBA32F texture, row 0 = (position,
    diffuse reflectance weight), row 1 = (normal, 0); ``count`` of them and the pole radius r."""

    texture: object
    count: int
    radius: float

    def free(self) -> None:
        self.texture = None  # Blender frees a GPUTexture with its last reference


def upload_receivers(receivers: dict) -> ViewReceivers:
    """``pipeline.view_receivers``'s dict (position (M, 3), normal (M, 3), weight (M,), radius) as
    :class:`ViewReceivers`; M = 0 gives a one-texel table of weight 0 and count 0."""
    position = np.asarray(receivers["position"], np.float64).reshape(-1, 3)
    normal = np.asarray(receivers["normal"], np.float64).reshape(-1, 3)
    weight = np.asarray(receivers["weight"], np.float64).reshape(-1)
    count = len(position)
    if normal.shape != position.shape or weight.shape != (count,):
        raise ValueError("view receivers need one position, normal and weight each")
    table = np.zeros((2, max(count, 1), 4), np.float32)
    table[0, :count, :3] = position
    table[0, :count, 3] = weight
    table[1, :count, :3] = normal
    radius = float(receivers["radius"])
    if not math.isfinite(radius) or radius < 0.0:
        raise ValueError(f"the view PDF's pole radius must be finite and >= 0, got {radius}")
    return ViewReceivers(texture_from_array(table), count, radius)


def _bind_common(shader, size: int, receivers: ViewReceivers, defensive: float) -> None:
    # The mixture stage declares the receivers for lib/brsm.glsl but reads none: the compiler drops them.
    set_uniform(shader.uniform_int, "rsm_size", int(size))
    set_uniform(shader.uniform_int, "view_pdf_sizes", (int(receivers.count), 0, 0, 0))
    set_uniform(shader.uniform_float, "view_pdf_params", (float(receivers.radius), float(defensive), 0.0, 0.0))
    set_uniform(shader.uniform_sampler, "view_receivers", receivers.texture)


def run(rsm_textures, receivers: ViewReceivers, defensive: float | None = None):
    """The defensive mixture of the view PDF and the light PDF for one RSM view
    (``vsgl_generation.RSMTextures``), as an (size, size) RGBA32F texture whose R channel is p
    (summing to 1 over the texels where any has weight, all 0 where none has). ``defensive`` β,
    reference ``DEFENSIVE_SHARE`` (read when called: the benchmark's sweep sets it) when None."""
    import gpu

    defensive = _reference.DEFENSIVE_SHARE if defensive is None else float(defensive)
    if not 0.0 <= defensive <= 1.0:
        raise ValueError(f"the defensive share must lie in [0, 1], got {defensive}")
    size = int(rsm_textures.size)
    groups = math.ceil(size / _TEXEL_GROUP[0])
    terms = gpu.types.GPUTexture((size, size), format="RGBA32F")
    sums = gpu.types.GPUTexture((1, 1), format="RGBA32F")
    pdf = gpu.types.GPUTexture((size, size), format="RGBA32F")

    shader = PASS.shader("terms")
    shader.bind()
    _bind_common(shader, size, receivers, defensive)
    for name in RSM.slot_names:
        shader.uniform_sampler(f"rsm_{name}", getattr(rsm_textures, name))
    shader.image("view_pdf_terms", terms)
    gpu.compute.dispatch(shader, groups, groups, 1)

    shader = PASS.shader("sums")
    shader.bind()
    shader.uniform_int("rsm_size", size)
    shader.image("view_pdf_terms", terms)
    shader.image("view_pdf_sums", sums)
    gpu.compute.dispatch(shader, 1, 1, 1)

    shader = PASS.shader("mixture")
    shader.bind()
    _bind_common(shader, size, receivers, defensive)
    shader.image("view_pdf_terms", terms)
    shader.image("view_pdf_sums", sums)
    shader.image("view_pdf_image", pdf)
    gpu.compute.dispatch(shader, groups, groups, 1)
    return pdf


PASS = GPUPass(
    name="brsm",
    label="View PDF",
    step=LIGHT_PASSES,
    shaders={
        "terms": ShaderSpec(_terms_interface, {"compute": "brsm/view_pdf_terms.comp.glsl"},
                            code=lambda: {"compute": RSM.glsl("samplers_load")}),
        "sums": ShaderSpec(_sums_interface, {"compute": "brsm/view_pdf_sums.comp.glsl"},
                           defines=lambda: {"VIEW_PDF_SUM_GROUP": SUM_GROUP}),
        "mixture": ShaderSpec(_mixture_interface, {"compute": "brsm/view_pdf.comp.glsl"}),
    },
    reads=(RSM.name,),  # each view's RSM texels; the receivers are an argument (upload_receivers)
    writes=("vsgl_pdf",),
    run=run,
)
