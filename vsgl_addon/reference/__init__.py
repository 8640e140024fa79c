# SPDX-License-Identifier: GPL-3.0-or-later
"""Float64 numpy reference of the add-on's formulas (../../docs/accuracy.md, formulas.md sec. 1-3).

Pure numpy, no bpy: the GLSL shaders are tested against these functions (same names), and these
functions are tested against numerical quadrature over the sphere (``quadrature``).

* ``sg``: spherical Gaussians, their product and integrals, the diffuse and specular SG lobes
  (000 app. A, 003).
* ``asg``: anisotropic spherical Gaussians, the ASG specular lobe (003), the SG x ASG convolution
  (000 app. C, 001 Eq. 11) and the ASG integral (001 Eq. 34).
* ``ggx``: GGX NDF, Smith masking and the microfacet BRDF (004 Eqs. 6-8, 001 Eq. 16).
* ``numerics``: the guarded float64 forms every module shares (twin of ``glsl/lib/math.glsl``).
* ``quadrature``: the sphere quadrature used to check them.
* ``solvers``: quadrature comparisons and fits of every approximation; ``measurements``: their
  figures as rows; ``accuracy``: the report, ``python -m vsgl_addon.reference.accuracy --write
  docs/accuracy.md`` regenerates the committed table.
"""

from .asg import asg_evaluate, asg_integral, asg_specular_lobe, sg_asg_convolution
from .ggx import fresnel_schlick, g1_distant, ggx_ndf, microfacet_brdf
from .sg import (
    COSINE_FLOOR,
    DIFFUSE_SHARPNESS,
    diffuse_lobe,
    ndf_sharpness,
    sg_evaluate,
    sg_integral,
    sg_lobe_normalized,
    sg_product,
    sg_product_integral,
    specular_lobe,
    specular_lobe_warp,
)

__all__ = [
    "COSINE_FLOOR",
    "DIFFUSE_SHARPNESS",
    "asg_evaluate",
    "asg_integral",
    "asg_specular_lobe",
    "diffuse_lobe",
    "fresnel_schlick",
    "g1_distant",
    "ggx_ndf",
    "microfacet_brdf",
    "ndf_sharpness",
    "sg_asg_convolution",
    "sg_evaluate",
    "sg_integral",
    "sg_lobe_normalized",
    "sg_product",
    "sg_product_integral",
    "specular_lobe",
    "specular_lobe_warp",
]
