# SPDX-License-Identifier: GPL-3.0-or-later
"""VSGL generation from a reflective shadow map (RSM), float64 ground truth (formulas.md §5).

Virtual spherical Gaussian lights (VSGLs) are clusters of the RSM's virtual point lights (VPLs,
one per texel), each described by an isotropic Gaussian in position and one spherical Gaussian
(SG) per reflection lobe for its radiant intensity (000 app. B). The clusters are kernels on the
RSM picked by filtered importance sampling (000 §3-4):

1. mip chains of the per-texel VPL moments of 000 app. B.3 and of the PDF (``mipmap.py``);
2. kernel centres x_i: a Fibonacci lattice (optionally Cranley-Patterson rotated) warped through
   the PDF mipmap by hierarchical sample warping (000 §3.2, app. D);
3. kernel level l_i: the modified kernel size (000 Eq. 3 with K, Algorithm 1) or the original one
   (000 Eq. 1, Křivánek-Colbert, with K);
4. cluster totals of the moments (000 Eq. 5, resp. Eq. 4) and from them the VSGL parameters
   (000 app. B.1-B.3);
5. or 003's simplified mode: two VSGLs (diffuse, specular) from the totals of the whole RSM.

Papers: 000 = Tokuyoshi, "Modified filtered importance sampling for virtual spherical Gaussian
lights" (CVM 2016); 003 = the Square Enix SG talk (2015), section 4 "単純化した実装".

Input: an :class:`RSM` (or a mapping with the same keys), arrays of shape (H, W, ...) with
H = W = 2^n (1x1 works). Image coordinates and mip conventions are those of ``mipmap.py``:
``kernel_center[:, 0]`` runs along W (columns), ``kernel_center[:, 1]`` along H (rows).

Scalar weights. 000 writes the VPL power Φ_j R_j as a scalar; the RSM holds RGB. The weights of
the averaged directions and positions (the denominators of ξ̄_v and µ_v, 000 app. B.1-B.2) are
the luminance of the RGB power (Rec. 709 / Blender's scene-linear coefficients), the same
luminance that makes the default PDF; amplitudes c_v and ``power`` stay RGB. Luminance is linear,
so lum(Σ ΦR) = Σ lum(ΦR) and the mipmapped RGB power gives the weights without extra channels.

Normalization of Eqs. 4-5. 000 treats f and p as functions on [0, 1]^2: p integrates to 1, and
Σ_j Φ_j R_j over a kernel = ∫ f g dx = 4^l/M · f̄ (000 app. B.3), so f is the texel value times M
and p is the texel probability times M. With F̄ the mipmapped *texel value* (mean over a block)
and p̄ the mipmapped *density* (top level = 1):

* modified (Eq. 5):  cluster estimate = M F̄(x_i, l_i) / (N p̄(x_i, l_i)).  With Eq. 3 this is
  4^l_i F̄ / K = (texel sum inside the kernel) / K: the K-fold overlap of K > 1 is divided out.
* original (Eq. 4):  cluster estimate = M F̄(x_i, l_i) / max(N p(x_i), 1), p(x_i) = M times the
  probability of the level-0 texel x_i lies in (the density the warp sampled x_i with, fetched
  without filtering: Eq. 4's denominator is "not filtered", 000 §4.1).

Summed over the N kernels both are estimates of the RSM total Σ_j Φ_j R_j: for a point x_i with
density p, E[f(x_i)/(N p(x_i))] = ∫ f dx / N; filtering at a fixed level preserves ∫ f dx
(``mipmap.py``), and 000 Eq. 5 divides by the same filter of p, so where p ∝ f the modified
estimate is exact for every lattice. Residual bias: the level varies with x_i (both modes), Eq. 5
divides by the filtered p̄ while x_i was drawn from the unfiltered p (modified), and Eq. 4's clamp max(N p, 1) replaces 1/(N p) by 1 where N p(x_i) < 1 (a kernel centre in a texel
whose probability is below 1/(N M)); we implement Eq. 4 as written. ``power`` is therefore an
estimate (the 2-VSGL mode is exact). Measured mean over lattice rotations (tests and report):
smooth PDFs, 32² RSM, N = 256: within 0.5 % for both modes; a PDF of iid noise not proportional
to the flux: Eq. 5 reads 0.5 % low at 128², N = 256 (kernels of ~8x8 texels) and 9 % low at 32²,
N = 256 (~2x2 texels), while Eq. 4 stays within ~1 % but varies 12-16 % from one lattice to the
next: the bias-for-variance trade of the modified kernels (000 §6, "Overlaps and gaps"). A PDF
that is 0 where the flux is not misses that flux entirely, as any importance sampling does.

Empty RSM (all flux 0) or a lobe with no power in a cluster: the VSGLs are still returned, with
power and amplitudes 0 and every other field finite (axis (0, 0, 1), sharpness 0, mean and
variance of the whole RSM, or 0 and the variance floor for an empty RSM); the kernel centres of
an empty RSM come from a uniform PDF. A fixed VSGL count keeps the GPU buffers fixed.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping

import numpy as np

from .. import settings  # the choices' one table (plain Python, no bpy)
from . import mipmap
from .numerics import dot, f64, norm, safe_normalize, safe_ratio
from .sg import DIFFUSE_HEMISPHERE_SCALE, DIFFUSE_SHARPNESS, sg_integral  # λ_d ≈ 2 (000 Eq. 6); A(λ) (000 app. A)

#: Rec. 709 luminance (Blender's scene-linear RGB): scalar weight of an RGB power.
LUMINANCE_WEIGHTS = np.array([0.2126, 0.7152, 0.0722])

#: Iterations of the bisection of 000 Algorithm 1 ("an iteration count of 12", 000 §3.2).
BISECTION_ITERATIONS = 12

#: Clamp |ξ̄_v| <= 1 - 2^-20, so λ_v = |ξ̄_v| / (1 - |ξ̄_v|) <= 2^20 - 1 ≈ 1.05e6 (000 app. B.1).
#: |ξ̄_v| -> 1 when every VPL of a cluster has the same, very sharp lobe (λ_v -> the VPLs' λ,
#: unbounded at grazing incidence). A float32 GPU computes 1 - |ξ̄_v| from float32 mip values whose
#: spacing below 1 is 2^-24: at 2^-20 the difference still holds 16 ulps (~6 % rounding), beyond it
#: λ_v would be rounding noise, up to inf at |ξ̄_v| = 1. The cap still covers the specular lobe of
#: roughness 1e-3 at normal incidence (λ_s = 2/α² / 4 = 5e5, 000 app. A.1), c_v = ΣΦR / A(λ_v)
#: <= ΣΦR · 1.7e5 and shading's λ products stay far inside float32.
MAX_AXIS_LENGTH = 1.0 - 2.0**-20
MAX_SHARPNESS = MAX_AXIS_LENGTH / (1.0 - MAX_AXIS_LENGTH)

#: σ_v² >= max(2^-20 · E|y|², 1e-12) (000 app. B.2). σ_v² = E|y|² - |µ_v|² is 0 for a cluster of
#: one VPL or of identical VPLs and can come out slightly negative by cancellation. The relative
#: term is where the paper's formula stops meaning anything in float32: its rounding error is a few
#: 2^-24 E|y|², so 2^-20 E|y|² is 16 ulps, and the reference clamps where a float32 GPU result
#: would be noise (both then agree). The absolute term (in scene units², 1e-12 m² = 1 µm²) covers
#: VPLs at the origin (E|y|² = 0): 1/σ_v² <= 1e12 and c_v / (2π σ_v²) stay finite in float32, and
#: shading such a VSGL gives the point-light limit, which is what one VPL is.
VARIANCE_FLOOR_RELATIVE = 2.0**-20
VARIANCE_FLOOR_ABSOLUTE = 1e-12

KERNEL_MODES = settings.KERNEL_MODES  # ("modified", "original", "two-vsgl"): settings.KERNELS

#: Channels of the per-texel moment image (mip-chained; "w" = luminance of the RGB power):
#: Σ Φ Rd, Σ w_d ξ̄_d, Σ Φ Rs, Σ w_s ξ̄_s (000 app. B.1, B.3), and the position moments of each
#: lobe, Σ w_d y, Σ w_d |y|², Σ w_s y, Σ w_s |y|². 000 app. B.2-B.3 keeps one pair, Σ w y and
#: Σ w |y|² with w = w_d + w_s: it is the sum of the two (``combined_position_moments``), so both
#: positional distributions (``POSITIONAL_DISTRIBUTIONS``) come from the same mip chains.
CH_DIFFUSE = slice(0, 3)
CH_DIFFUSE_DIRECTION = slice(3, 6)
CH_SPECULAR = slice(6, 9)
CH_SPECULAR_DIRECTION = slice(9, 12)
CH_DIFFUSE_POSITION = slice(12, 15)
CH_DIFFUSE_POSITION_SQUARED = 15
CH_SPECULAR_POSITION = slice(16, 19)
CH_SPECULAR_POSITION_SQUARED = 19
MOMENT_CHANNELS = 20

#: Where a VSGL's lobes are placed. "shared": 000 app. B.2 as written, one isotropic Gaussian per
#: VSGL weighted by Φ (Rd + Rs) for both lobes ("not divided into diffuse and specular components
#: in order to avoid the increase of visibility tests"). "per-lobe": each lobe's own Gaussian,
#: weighted by its own power (Φ Rd, resp. Φ Rs); it differs only in clusters that mix surfaces of
#: different materials, where the shared mean moves one surface's light onto the other (000 §6,
#: Fig. 7's world-space limitation). The add-on has no VSGL visibility, so the paper's reason for
#: sharing does not apply; "shared" stays available and the combined ``mean``/``variance`` are
#: always returned (what a per-VSGL shadow map would use).
POSITIONAL_DISTRIBUTIONS = settings.POSITIONAL_DISTRIBUTIONS  # ("per-lobe", "shared"): settings.POSITIONS

OUTPUT_KEYS = (
    "mean",
    "variance",
    "diffuse_mean",
    "diffuse_variance",
    "specular_mean",
    "specular_variance",
    "diffuse_amplitude",
    "diffuse_axis",
    "diffuse_sharpness",
    "specular_amplitude",
    "specular_axis",
    "specular_sharpness",
    "power",
    "kernel_center",
    "kernel_level",
)

FALLBACK_AXIS = np.array([0.0, 0.0, 1.0])


def luminance(rgb) -> np.ndarray:
    """Rec. 709 luminance of RGB values (..., 3)."""
    return f64(rgb) @ LUMINANCE_WEIGHTS


@dataclass(frozen=True)
class RSM:
    """A reflective shadow map: one VPL per texel (formulas.md §4), arrays (H, W, ...), H = W = 2^n.

    position            (H, W, 3)  VPL position y (world space)
    normal              (H, W, 3)  surface normal n (axis of the diffuse lobe, 000 Eq. 6)
    flux_diffuse        (H, W, 3)  Φ·Rd, RGB, >= 0
    flux_specular       (H, W, 3)  Φ·Rs, RGB, >= 0
    specular_axis       (H, W, 3)  ξ_s of the warped specular lobe (000 Eq. 7)
    specular_sharpness  (H, W)     λ_s of the warped specular lobe, >= 0 (inf = mirror is allowed)

    Directions are renormalized here (a zero vector counts as an isotropic lobe). Positions,
    directions and sharpness of texels without flux are ignored, so background texels may hold
    anything, NaN included.
    """

    position: np.ndarray
    normal: np.ndarray
    flux_diffuse: np.ndarray
    flux_specular: np.ndarray
    specular_axis: np.ndarray
    specular_sharpness: np.ndarray

    @classmethod
    def coerce(cls, rsm) -> "RSM":
        """Accept an RSM or a mapping with the field names; validate shapes and flux."""
        if isinstance(rsm, RSM):
            fields = {name: getattr(rsm, name) for name in cls.__dataclass_fields__}
        elif isinstance(rsm, Mapping):
            fields = {name: rsm[name] for name in cls.__dataclass_fields__}
        else:
            raise TypeError(f"expected an RSM or a mapping, got {type(rsm).__name__}")
        fields = {name: f64(value) for name, value in fields.items()}
        size = mipmap.check_square_power_of_two(fields["position"].shape)
        for name, value in fields.items():
            expected = (size, size) if name == "specular_sharpness" else (size, size, 3)
            if value.shape != expected:
                raise ValueError(f"{name} must have shape {expected}, got {value.shape}")
        for name in ("flux_diffuse", "flux_specular"):
            value = fields[name]
            if not np.all(np.isfinite(value)) or np.any(value < 0.0):
                raise ValueError(f"{name} must be finite and non-negative")
        return cls(**fields)

    @property
    def size(self) -> int:
        return self.position.shape[0]

    @property
    def texel_count(self) -> int:
        """M, the number of texels (000 §3.1)."""
        return self.size * self.size


def unit_or_zero(vectors, mask):
    """Normalize where mask and the length is positive and finite; zero elsewhere."""
    vectors = np.where(mask[..., None], vectors, 0.0)
    length = norm(vectors)
    ok = mask & (length > 0.0) & np.isfinite(length)
    return np.where(ok[..., None], vectors / np.where(ok, length, 1.0)[..., None], 0.0)


def toksvig_mean_direction(axis, sharpness):
    """ξ̄ = λ/(λ+1) ξ (Toksvig; 000 app. B.1), written ξ / (1 + 1/λ): finite for λ = 0 and λ = inf."""
    with np.errstate(divide="ignore"):
        factor = 1.0 / (1.0 + 1.0 / sharpness)
    return factor[..., None] * axis


def texel_moments(rsm: RSM) -> np.ndarray:
    """Per-texel VPL moments (H, W, 20) of 000 app. B.3 (channel layout: ``CH_*``).

    Σ Φ Rd, Σ w_d ξ̄_d, Σ Φ Rs, Σ w_s ξ̄_s, Σ w_d y, Σ w_d |y|², Σ w_s y, Σ w_s |y|² with
    w_d = lum(Φ Rd), w_s = lum(Φ Rs); ξ̄_d = λ_d/(λ_d + 1) n with λ_d = DIFFUSE_SHARPNESS (000 Eq. 6)
    and ξ̄_s = λ_s/(λ_s + 1) ξ_s (000 Eq. 7). Texels without power contribute zeros everywhere.
    """
    w_d = luminance(rsm.flux_diffuse)
    w_s = luminance(rsm.flux_specular)
    lit_d = w_d > 0.0
    lit_s = w_s > 0.0
    lit = (w_d + w_s) > 0.0
    normal = unit_or_zero(rsm.normal, lit_d)
    spec_axis = unit_or_zero(rsm.specular_axis, lit_s)
    spec_sharpness = np.where(lit_s, rsm.specular_sharpness, 0.0)
    if np.any(np.isnan(spec_sharpness)) or np.any(spec_sharpness < 0.0):
        raise ValueError("specular_sharpness of lit texels must be >= 0 (inf allowed)")
    position = np.where(lit[..., None], rsm.position, 0.0)
    if not np.all(np.isfinite(position)):
        raise ValueError("position of lit texels must be finite")
    out = np.zeros(rsm.position.shape[:2] + (MOMENT_CHANNELS,))
    out[..., CH_DIFFUSE] = rsm.flux_diffuse
    out[..., CH_DIFFUSE_DIRECTION] = w_d[..., None] * toksvig_mean_direction(
        normal, np.full(w_d.shape, float(DIFFUSE_SHARPNESS))
    )
    out[..., CH_SPECULAR] = rsm.flux_specular
    out[..., CH_SPECULAR_DIRECTION] = w_s[..., None] * toksvig_mean_direction(
        spec_axis, spec_sharpness
    )
    squared = dot(position, position)
    out[..., CH_DIFFUSE_POSITION] = w_d[..., None] * position
    out[..., CH_DIFFUSE_POSITION_SQUARED] = w_d * squared
    out[..., CH_SPECULAR_POSITION] = w_s[..., None] * position
    out[..., CH_SPECULAR_POSITION_SQUARED] = w_s * squared
    return out


def combined_position_moments(totals):
    """Σ w y and Σ w |y|² with w = w_d + w_s (000 app. B.2-B.3) from moment totals (..., 20)."""
    totals = f64(totals)
    return (totals[..., CH_DIFFUSE_POSITION] + totals[..., CH_SPECULAR_POSITION],
            totals[..., CH_DIFFUSE_POSITION_SQUARED] + totals[..., CH_SPECULAR_POSITION_SQUARED])


def default_pdf(rsm: RSM) -> np.ndarray:
    """Luminance of Φ (Rd + Rs) per texel normalized to sum 1; uniform if the RSM has no power."""
    return normalize_pdf(luminance(rsm.flux_diffuse + rsm.flux_specular))


def normalize_pdf(pdf) -> np.ndarray:
    """Texel probabilities (H, W) summing to 1; an all-zero image becomes uniform."""
    pdf = f64(pdf)
    if pdf.ndim != 2:
        raise ValueError(f"a PDF image has shape (H, W), got {pdf.shape}")
    if not np.all(np.isfinite(pdf)) or np.any(pdf < 0.0):
        raise ValueError("a PDF image must be finite and non-negative")
    total = pdf.sum()
    if total <= 0.0:
        return np.full(pdf.shape, 1.0 / pdf.size)
    return pdf / total


@dataclass(frozen=True)
class RSMMipmaps:
    """Mip chains of an RSM: ``moments`` (levels of (h, w, 20), means of ``texel_moments``),
    ``pdf`` (levels of (h, w), the density p = M · texel probability, so the top level is 1) and
    ``jump`` (levels of (h, w), means of w · [texel beside a depth discontinuity] with w =
    lum(Φ (Rd + Rs)), :func:`texel_jumps`; what :func:`straddles` reads)."""

    moments: list
    pdf: list
    texel_count: int
    jump: list | None = None

    @property
    def top_level(self) -> int:
        return len(self.pdf) - 1


def build_mipmaps(rsm, pdf=None) -> RSMMipmaps:
    """The mipmapped RSM of 000 §4.1 / Fig. 4, the PDF mipmap (000 §3.2) and that of the power on
    texels beside a depth discontinuity (:func:`straddles`)."""
    rsm = RSM.coerce(rsm)
    probability = default_pdf(rsm) if pdf is None else normalize_pdf(pdf)
    if probability.shape != (rsm.size, rsm.size):
        raise ValueError(f"pdf must have shape {(rsm.size, rsm.size)}, got {probability.shape}")
    weight = luminance(rsm.flux_diffuse + rsm.flux_specular)
    return RSMMipmaps(
        moments=mipmap.build_mip_chain(texel_moments(rsm)),
        pdf=mipmap.build_mip_chain(probability * rsm.texel_count),
        texel_count=rsm.texel_count,
        jump=mipmap.build_mip_chain(weight * texel_jumps(rsm)),
    )


def _lit_neighbour(position, lit, axis, step):
    """The neighbour ``step`` (±1) texels along image ``axis`` (0 rows, 1 columns) of every texel:
    its position (H, W, 3), and (H, W) whether both texels are lit and the neighbour is inside the
    image."""
    size = position.shape[axis]
    index = np.arange(size) + step
    inside = (index >= 0) & (index < size)
    inside = inside[:, None] if axis == 0 else inside[None, :]
    return np.roll(position, -step, axis=axis), lit & np.roll(lit, -step, axis=axis) & inside


def _one_sided_difference(position, lit, axis):
    """(H, W, 3) the shorter of the forward and backward differences of ``position`` along image
    ``axis`` (0 rows, 1 columns) between lit texels, zero where neither neighbour is lit."""
    best = np.zeros(position.shape)
    best_length = np.full(position.shape[:2], np.inf)
    for step in (1, -1):
        neighbour, ok = _lit_neighbour(position, lit, axis, step)
        difference = (neighbour - position) * step
        length = norm(difference)
        better = ok & (length < best_length)
        best = np.where(better[..., None], difference, best)
        best_length = np.where(better, length, best_length)
    return best


def texel_areas(rsm) -> np.ndarray:
    """(H, W) the surface area each lit texel covers: |Δ_u y × Δ_v y| of its position's one-sided
    differences to its lit neighbours along the image's columns and rows, the shorter side of each
    (across a depth discontinuity the other side's difference spans the jump, not the texel);
    |Δ|² of the one axis with a lit neighbour when the other has none; 0 for a texel without a lit
    neighbour and for unlit texels. Twin of glsl/vsgl_generation/texel_moments.frag.glsl."""
    rsm = RSM.coerce(rsm)
    lit = luminance(rsm.flux_diffuse + rsm.flux_specular) > 0.0
    position = np.where(lit[..., None], rsm.position, 0.0)
    du = _one_sided_difference(position, lit, 1)
    dv = _one_sided_difference(position, lit, 0)
    crossed = norm(np.cross(du, dv))
    has_u, has_v = dot(du, du) > 0.0, dot(dv, dv) > 0.0
    area = np.where(has_u & has_v, crossed, np.where(has_u, dot(du, du), dot(dv, dv)))
    return np.where(lit, area, 0.0)


def texel_jumps(rsm, jump_texels=None) -> np.ndarray:
    """(H, W) bool: lit texels with a lit 4-neighbour farther than ``jump_texels`` (JUMP_TEXELS when
    None) times the texel's own size √a (:func:`texel_areas`) in space: the two sides of a depth
    discontinuity (a wall's top beside the ground below it, a silhouette against what lies
    behind). Texels without an area (no lit neighbour) have no jump. Twin of
    glsl/vsgl_generation/texel_moments.frag.glsl."""
    rsm = RSM.coerce(rsm)
    jump_texels = JUMP_TEXELS if jump_texels is None else float(jump_texels)
    lit = luminance(rsm.flux_diffuse + rsm.flux_specular) > 0.0
    position = np.where(lit[..., None], rsm.position, 0.0)
    reach = jump_texels * np.sqrt(texel_areas(rsm))
    jump = np.zeros(lit.shape, bool)
    for axis in (0, 1):
        for step in (1, -1):
            neighbour, ok = _lit_neighbour(position, lit, axis, step)
            jump |= ok & (reach > 0.0) & (norm(neighbour - position) > reach)
    return jump


#: A 4-neighbour this many texel sizes away in space is across a depth discontinuity
#: (:func:`texel_jumps`): a surface at 86° from the light has texels 4x longer than wide.
JUMP_TEXELS = 4.0

#: 000 §4 clusters the VPLs of a kernel on the RSM's image plane, which puts the two sides of a
#: depth discontinuity (a wall's sunlit back beside the ground beyond its top) in one cluster: its
#: mean floats between them (in the air, inside the wall) and one lobe mixes a surface facing away
#: from the receivers with one facing them (benchmarks/courtyard_leak.py: the sun courtyard's
#: clusters of the wall's back and the courtyard's ground bring it 0.25 of Cycles' light too much
#: at N = 256 and at N = 1024). A kernel whose filter holds more than STRADDLE_SHARE of its power on
#: texels beside a jump (:func:`texel_jumps`) descends a level (:func:`kernel_level_unstraddled`)
#: until it holds none (or reaches level 0). The generation's default (True: descend; False:
#: 000's kernels); the renderer asks for the descent per light (pipeline.SPLIT_LIGHT_TYPES).
SPLIT_AT_JUMPS = False
#: The most levels a kernel descends (:func:`kernel_level_unstraddled`).
MAX_DESCENT = 16
#: A kernel that still straddles at level 0 moves onto its own texel's centre (a VPL there) when
#: True, or keeps its level-0 bilinear taps across the jump (:func:`kernel_level_unstraddled`).
SNAP_TO_TEXEL = True
#: The share of a kernel's power on jump texels it may hold (:func:`straddles`).
STRADDLE_SHARE = 0.0
#: A kernel over a jump straddles only where its surfaces face different ways: its diffuse lobes'
#: Toksvig mean direction |Σ w_d ξ̄_d| / Σ w_d (000 app. B.1) shorter than NORMAL_AGREEMENT times
#: one surface's, λ_d / (λ_d + 1) (two normals at 90° in shares q, 1 − q: √(1 − 2q(1 − q)) of
#: it, 0.95 at q = 0.05). Layers facing one way (a table's top over the floor) keep 000's kernels:
#: their descended, VPL-like VSGLs brought more noise than the floating mean cost
#: (benchmarks/split_at_jumps.py). 0: every kernel over a jump straddles.
NORMAL_AGREEMENT = 0.95


def straddles(maps: RSMMipmaps, center, level) -> np.ndarray:
    """(N,) True where the kernel at ``center`` (N, 2), ``level`` (N,) holds more than
    STRADDLE_SHARE of its power on texels beside a depth discontinuity (the same trilinear filter
    of the moments and of the power on jump texels, RSMMipmaps.jump) and, with NORMAL_AGREEMENT
    > 0 and diffuse power, its diffuse normals disagree (see NORMAL_AGREEMENT)."""
    level = f64(level)
    filtered = mipmap.trilinear(maps.moments, center, level)
    weight = luminance(filtered[..., CH_DIFFUSE] + filtered[..., CH_SPECULAR])
    jump = mipmap.trilinear(maps.jump, center, level)
    diffuse = luminance(filtered[..., CH_DIFFUSE])
    length = norm(filtered[..., CH_DIFFUSE_DIRECTION])
    one_surface = DIFFUSE_SHARPNESS / (DIFFUSE_SHARPNESS + 1.0)
    disagree = (NORMAL_AGREEMENT <= 0.0) | ~(diffuse > 0.0) | (length < NORMAL_AGREEMENT * one_surface * diffuse)
    return (weight > 0.0) & (jump > STRADDLE_SHARE * weight) & disagree


def kernel_level_unstraddled(maps: RSMMipmaps, center, texel, level, split=None):
    """(level (N,), center (N, 2)): every kernel that :func:`straddles` moved down one level at a
    time until it no longer does (``split``: SPLIT_AT_JUMPS when None; False returns ``level`` and
    ``center``), and one that still does at level 0 (its bilinear taps across the jump) moved onto
    the centre of its own texel ``texel`` (N, 2) (row, column; the warp's), where it is that
    texel's VPL: its cluster then lies on one side of the discontinuity. 000 Eq. 5 divides by the
    PDF filtered at the new level and centre, so where p ∝ the power the VSGL keeps its power and
    covers a smaller part of the RSM (the kernels no longer tile the RSM there: 000 §6's overlaps
    and gaps, unbiased over lattice rotations)."""
    split = SPLIT_AT_JUMPS if split is None else bool(split)
    level, center = f64(level).copy(), f64(center).copy()
    if not split or maps.jump is None:
        return level, center
    for _ in range(min(maps.top_level + 1, MAX_DESCENT)):
        down = straddles(maps, center, level) & (level > 0.0)
        if not down.any():
            break
        level = np.where(down, np.maximum(level - 1.0, 0.0), level)
    size = maps.pdf[0].shape[0]
    own = (np.asarray(texel)[:, ::-1] + 0.5) / size  # (column, row) → uv
    snap = straddles(maps, center, level) & (level <= 0.0) & SNAP_TO_TEXEL
    return level, np.where(snap[:, None], own, center)


def kernel_pdf_mass(pdf_chain, uv, level, texel_count) -> np.ndarray:
    """4^l / M · p̄(x, l): the PDF mass of a kernel (left side of 000 Eq. 3)."""
    level = f64(level)
    return 4.0**level / texel_count * mipmap.trilinear(pdf_chain, uv, level)


def kernel_level_modified(pdf_chain, uv, k, vsgl_count, texel_count,
                          iterations=BISECTION_ITERATIONS) -> np.ndarray:
    """Modified kernel size: solve 4^l / M · p̄(x_i, l) = K / N by bisection (000 Eq. 3, Alg. 1).

    l in [0, top]; l_min <- l where the left side is below K/N, else l_max <- l; the result is the
    final midpoint, so it lies strictly inside [0, top] (within top · 2^-(iterations+1) of an end
    when the equation has no root inside). The comparisons alone steer the bisection, so l_i is
    non-decreasing in K/N even where the left side is not monotone in l (trilinear p̄ need not be).
    """
    per_level = mipmap.sample_all_levels(pdf_chain, uv)
    top = per_level.shape[0] - 1
    target = float(k) / float(vsgl_count)
    count = per_level.shape[1]
    l_min = np.zeros(count)
    l_max = np.full(count, float(top))
    for _ in range(int(iterations)):
        level = 0.5 * (l_min + l_max)
        mass = 4.0**level / texel_count * mipmap.interpolate_levels(per_level, level)
        below = mass < target
        l_min = np.where(below, level, l_min)
        l_max = np.where(below, l_max, level)
    return 0.5 * (l_min + l_max)


def kernel_level_original(pdf_at_center, k, vsgl_count, texel_count, top_level) -> np.ndarray:
    """Original kernel size: 4^l / M = min(K / (N p(x_i)), 1) (000 Eq. 1; Křivánek-Colbert).

    l = log4(M · min(K / (N p), 1)), clamped to [0, top]. l < 0 (a texel of probability p/M above
    K/N) would ask for a kernel smaller than a texel, which the mipmap cannot resolve. p is the
    unfiltered density at x_i, so l jumps between texels: the weakness 000 §3.1 points out.
    """
    p = np.maximum(f64(pdf_at_center), np.finfo(np.float64).tiny)
    area = np.minimum(float(k) / (float(vsgl_count) * p), 1.0)
    return np.clip(0.5 * np.log2(texel_count * area), 0.0, float(top_level))


def vsgl_lobe(power, direction_sum):
    """SG of one lobe from Σ ΦR (RGB) and Σ w ξ̄ (000 app. B.1): amplitude, axis, sharpness."""
    weight = luminance(power)
    mean_direction = safe_ratio(direction_sum, weight)
    length = norm(mean_direction)
    axis = safe_normalize(mean_direction, FALLBACK_AXIS, length)
    # |ξ̄_v| <= 1 holds for any non-negative weighting; the clamp keeps λ_v finite (MAX_AXIS_LENGTH).
    length = np.minimum(length, MAX_AXIS_LENGTH)
    sharpness = length / (1.0 - length)
    amplitude = power / sg_integral(sharpness)[..., None]
    return amplitude, axis, sharpness


def vsgl_position(weight, position_sum, position_squared_sum, fallback_mean, fallback_variance):
    """µ_v and σ_v² = E|y|² - |µ_v|² (000 app. B.2), clamped to the variance floor."""
    has = weight > 0.0
    mean = np.where(has[..., None], safe_ratio(position_sum, weight), fallback_mean)
    second = safe_ratio(position_squared_sum, weight)
    variance = np.where(has, second - dot(mean, mean), fallback_variance)
    floor = np.maximum(VARIANCE_FLOOR_RELATIVE * second, VARIANCE_FLOOR_ABSOLUTE)
    return mean, np.maximum(variance, np.where(has, floor, VARIANCE_FLOOR_ABSOLUTE))


def _check_positional_distribution(positional_distribution):
    if positional_distribution not in POSITIONAL_DISTRIBUTIONS:
        raise ValueError(f"positional_distribution must be one of {POSITIONAL_DISTRIBUTIONS}, "
                         f"got {positional_distribution!r}")


def vsgl_parameters(totals, fallback_mean=None, fallback_variance=None,
                    positional_distribution="per-lobe") -> dict:
    """VSGL parameters from cluster totals (..., 20) of ``texel_moments`` (000 app. B.1-B.3).

    Per lobe: ξ̄_v = Σ w ξ̄ / Σ w, ξ_v = ξ̄_v / |ξ̄_v|, λ_v = |ξ̄_v| / (1 - |ξ̄_v|), c_v = Σ ΦR / A(λ_v),
    the diffuse lobe's times ``sg.DIFFUSE_HEMISPHERE_SCALE``: its texels' lobes are 000 Eq. 6's SG
    normalized over the hemisphere (each re-emits Φ·Rd above its surface), so the Toksvig sum of
    000 app. B.1 is that factor times the sphere-normalized one.
    Position (000 app. B.2): ``mean``/``variance`` µ_v = Σ w y / Σ w, σ_v² = Σ w |y|² / Σ w - |µ_v|²
    with w = lum(Φ (Rd + Rs)), always; ``diffuse_mean``/``diffuse_variance`` and
    ``specular_mean``/``specular_variance``, what shading places each lobe with, are the same
    formulas with w = lum(Φ Rd), resp. lum(Φ Rs), for ``positional_distribution`` "per-lobe", and
    copies of ``mean``/``variance`` for "shared" (``POSITIONAL_DISTRIBUTIONS``). A lobe without
    power takes the combined position. Any common positive scale of the totals cancels except in
    c_v and ``power``.
    """
    _check_positional_distribution(positional_distribution)
    totals = f64(totals)
    if fallback_mean is None:
        fallback_mean = np.zeros(3)
    if fallback_variance is None:
        fallback_variance = VARIANCE_FLOOR_ABSOLUTE
    d_power, s_power = totals[..., CH_DIFFUSE], totals[..., CH_SPECULAR]
    d_amp, d_axis, d_sharp = vsgl_lobe(d_power, totals[..., CH_DIFFUSE_DIRECTION])
    d_amp = d_amp * DIFFUSE_HEMISPHERE_SCALE
    s_amp, s_axis, s_sharp = vsgl_lobe(s_power, totals[..., CH_SPECULAR_DIRECTION])
    power = d_power + s_power
    position_sum, position_squared_sum = combined_position_moments(totals)
    mean, variance = vsgl_position(luminance(power), position_sum, position_squared_sum,
                               fallback_mean, fallback_variance)
    if positional_distribution == "per-lobe":
        d_mean, d_variance = vsgl_position(luminance(d_power), totals[..., CH_DIFFUSE_POSITION],
                                       totals[..., CH_DIFFUSE_POSITION_SQUARED], mean, variance)
        s_mean, s_variance = vsgl_position(luminance(s_power), totals[..., CH_SPECULAR_POSITION],
                                       totals[..., CH_SPECULAR_POSITION_SQUARED], mean, variance)
    else:
        d_mean, d_variance, s_mean, s_variance = mean, variance, mean.copy(), variance.copy()
    return {
        "mean": mean,
        "variance": variance,
        "diffuse_mean": d_mean,
        "diffuse_variance": d_variance,
        "specular_mean": s_mean,
        "specular_variance": s_variance,
        "diffuse_amplitude": d_amp,
        "diffuse_axis": d_axis,
        "diffuse_sharpness": d_sharp,
        "specular_amplitude": s_amp,
        "specular_axis": s_axis,
        "specular_sharpness": s_sharp,
        "power": power,
    }


def _rsm_fallback(top_moments):
    """Mean and variance of the whole RSM (its 1x1 level): the position of power-less clusters."""
    totals = top_moments[0, 0]
    power = totals[CH_DIFFUSE] + totals[CH_SPECULAR]
    position_sum, position_squared_sum = combined_position_moments(totals)
    mean, variance = vsgl_position(
        luminance(power), position_sum, position_squared_sum, np.zeros(3),
        VARIANCE_FLOOR_ABSOLUTE,
    )
    return mean, float(variance)


def lattice_rotation(seed=0, rotation=None) -> np.ndarray:
    """Cranley-Patterson shift of the lattice: ``rotation`` if given, else uniform from ``seed``
    (numpy's default_rng), else (seed None) no shift."""
    if rotation is not None:
        rotation = f64(rotation).reshape(2)
        return rotation - np.floor(rotation)
    if seed is None:
        return np.zeros(2)
    return np.random.default_rng(seed).random(2)


def two_vsgls(rsm) -> dict:
    """003's simplified mode: one diffuse-only and one specular-only VSGL from whole-RSM totals.

    No mipmap and no sampling: a parallel sum over the RSM (003, "VSGLのパラメータ: Reflective
    Shadow Maps全領域の平均"). Row 0 carries only the diffuse lobe, row 1 only the specular lobe.
    003 does not say which power weights each VSGL's position; a VSGL that emits only one lobe is
    placed at that lobe's power centroid (weights lum(Φ Rd), resp. lum(Φ Rs)), which is what both
    positional distributions give for a cluster holding a single lobe. ``power`` is exact:
    Σ Φ Rd and Σ Φ Rs, summing to the RSM total.
    """
    rsm = RSM.coerce(rsm)
    totals = texel_moments(rsm).reshape(-1, MOMENT_CHANNELS).sum(axis=0)
    total_mean, total_variance = _rsm_fallback(totals[None, None])
    rows = np.zeros((2, MOMENT_CHANNELS))
    for channel in (CH_DIFFUSE, CH_DIFFUSE_DIRECTION, CH_DIFFUSE_POSITION, CH_DIFFUSE_POSITION_SQUARED):
        rows[0, channel] = totals[channel]
    for channel in (CH_SPECULAR, CH_SPECULAR_DIRECTION, CH_SPECULAR_POSITION,
                    CH_SPECULAR_POSITION_SQUARED):
        rows[1, channel] = totals[channel]
    out = vsgl_parameters(rows, total_mean, total_variance)
    out["kernel_center"] = np.full((2, 2), 0.5)
    out["kernel_level"] = np.full(2, float(mipmap.mip_level_count(rsm.size) - 1))
    out["rsm_total_power"] = (rsm.flux_diffuse + rsm.flux_specular).reshape(-1, 3).sum(axis=0)
    return out


def cluster_totals(maps: RSMMipmaps, center, texel, k, vsgl_count, kernel="modified", split_at_jumps=None):
    """Kernel levels (N), centres (N, 2) and cluster estimates (N, 20) of the moments at warped
    kernel centres.

    ``center`` (N, 2) and ``texel`` (N, 2) as returned by ``mipmap.warp_hierarchical``.
    'modified': l_i from Eq. 3 (Algorithm 1), lowered where the kernel straddles a depth
    discontinuity (:func:`kernel_level_unstraddled`, ``split_at_jumps``: SPLIT_AT_JUMPS when
    None), estimate M F̄(x_i, l_i) / (N p̄(x_i, l_i)) (Eq. 5).
    'original': l_i from Eq. 1, estimate M F̄(x_i, l_i) / max(N p(x_i), 1) (Eq. 4).
    """
    level, center, scale = _cluster_scale(maps, center, texel, k, vsgl_count, kernel, split_at_jumps)
    filtered = mipmap.trilinear(maps.moments, center, level)
    return level, center, filtered * scale[:, None]


def _cluster_scale(maps: RSMMipmaps, center, texel, k, vsgl_count, kernel, split_at_jumps):
    """(level, center, M / denominator) of :func:`cluster_totals`: the cluster estimate is the
    trilinear filter of the moments at (center, level) times the last."""
    texel_count = maps.texel_count
    if kernel == "modified":
        level = kernel_level_modified(maps.pdf, center, k, vsgl_count, texel_count)
        level, center = kernel_level_unstraddled(maps, center, texel, level, split_at_jumps)
        # Eq. 5: numerator and denominator filtered with the same kernel.
        denominator = vsgl_count * mipmap.trilinear(maps.pdf, center, level)
    elif kernel == "original":
        pdf_at_center = maps.pdf[0][texel[:, 0], texel[:, 1]]
        level = kernel_level_original(pdf_at_center, k, vsgl_count, texel_count, maps.top_level)
        # Eq. 4 as written: unfiltered density; with K = 1 the clamp max(N p, 1) makes a kernel that
        # covers the whole RSM (N p <= 1) return the RSM total rather than total / (N p).
        denominator = np.maximum(vsgl_count * pdf_at_center, 1.0)
    else:
        raise ValueError(f"kernel must be 'modified' or 'original', got {kernel!r}")
    # p̄ > 0 at a warped centre (its own texel has bilinear weight >= 1/4 at every level); the
    # floor only guards against a subnormal PDF.
    denominator = np.maximum(denominator, np.finfo(np.float64).tiny)
    return level, center, texel_count / denominator


# --- Plane-split clusters --------------------------------------------------------------------

#: 000 §4 clusters the VPLs of an RSM-image kernel. Where a kernel spans a room's corner (a point
#: light's cube face over a floor and two walls, a few VSGLs per view), one SG lobe and one
#: isotropic Gaussian stand for several planes: the Toksvig mean of the normals is short (λ_v ≈ 1
#: instead of 2), the lobe sends light behind both surfaces and the mean floats in front of the
#: corner. Measured against each cluster's own texels (benchmarks/results/vsgl_aggregation*.md,
#: no visibility, N = 256): the 24-light room's VSGLs give 0.928 of their texels' light, its
#: corner clusters 0.891. A **plane-split cluster** keeps 000's kernel (its level, centre and
#: Eq. 5 weights, so the power is unchanged) and bins its diffuse moments by the normal class of
#: the mip texels PLANE_SPLIT_DEPTH levels under each of its trilinear taps (the kernel's filter,
#: regrouped); each class holding PLANE_SPLIT_SHARE of the diffuse power or more becomes a VSGL of
#: its own (up to PLANE_SPLIT_EXTRA more), built with 000 app. B.1-B.2 from its moments. The
#: kernel's VSGL keeps the largest class, the small ones and the whole specular lobe. Only kernels
#: whose diffuse normals disagree (NORMAL_AGREEMENT, as for the jumps) split, so a flat cluster's
#: VSGL is 000's. The what-if (same kernels, float64, benchmarks/results/vsgl_aggregation_blocks.md):
#: the 24-light room 0.928 -> 0.964 of the texels' light, the closed room 0.986 -> 1.012, the
#: Cornell box 0.955 -> 0.952. It departs from 000 §4: a frame has N VSGLs plus the extra planes'.
#: The generation's default (the renderer asks per light type: pipeline.PLANE_SPLIT_LIGHT_TYPES).
PLANE_SPLIT = False
#: Levels under each trilinear tap whose texels are binned by their mean normal's class: 1 gives
#: 0.955, 2 0.953 and 3 0.964 of the texels' light on the 24-light room; each texel's own normal
#: (level 0) 0.969.
PLANE_SPLIT_DEPTH = 3
#: Share of a cluster's diffuse power (luminance) a class needs to become a VSGL of its own.
PLANE_SPLIT_SHARE = 0.05
#: Most VSGLs a kernel adds: the table keeps PLANE_SPLIT_EXTRA slots per kernel after the N
#: kernels' VSGLs, and the unused ones (power 0) are dropped when it is read.
PLANE_SPLIT_EXTRA = 3
NORMAL_CLASSES = 6
_DIFFUSE_CHANNELS = np.r_[0:6, 12:16]


def normal_class(direction) -> np.ndarray:
    """Class 0-5 of each direction (..., 3): 2 × its dominant axis + 1 where that component is
    negative; ties take the first axis (np.argmax), a zero vector class 0."""
    direction = f64(direction)
    dominant = np.argmax(np.abs(direction), axis=-1)
    component = np.take_along_axis(direction, dominant[..., None], axis=-1)[..., 0]
    return 2 * dominant + (component < 0.0)


def normals_disagree(totals) -> np.ndarray:
    """(N,) True where a cluster's diffuse lobes' Toksvig mean direction is shorter than
    NORMAL_AGREEMENT times one surface's (:func:`straddles`' test without the jump)."""
    totals = f64(totals)
    diffuse = luminance(totals[..., CH_DIFFUSE])
    length = norm(totals[..., CH_DIFFUSE_DIRECTION])
    one_surface = DIFFUSE_SHARPNESS / (DIFFUSE_SHARPNESS + 1.0)
    return (diffuse > 0.0) & (length < NORMAL_AGREEMENT * one_surface * diffuse)


def plane_class_moments(maps: RSMMipmaps, center, level) -> np.ndarray:
    """(N, 6, 20): the trilinear filter of the moments at (center, level) (``mipmap.trilinear``,
    unscaled) with its diffuse channels split by normal class. Each tap texel at level L is the
    mean of its 4^(L - b) texels at b = max(L - PLANE_SPLIT_DEPTH, 0), each binned by the class of
    its Σ w_d ξ̄_d (:func:`normal_class`); the classes sum to the filter's diffuse channels, the
    specular channels are 0."""
    center, level = f64(center).reshape(-1, 2), f64(level).reshape(-1)
    top = maps.top_level
    out = np.zeros((len(level), NORMAL_CLASSES, MOMENT_CHANNELS))
    for n, (uv, l) in enumerate(zip(center, level)):
        l = min(max(float(l), 0.0), float(top))
        lower = min(int(np.floor(l)), top)
        upper = min(lower + 1, top)
        fraction = l - lower
        for tap_level, share in ((lower, 1.0 - fraction), (upper, fraction)):
            if not share > 0.0:
                continue
            side = maps.moments[tap_level].shape[0]
            s, t = uv[0] * side - 0.5, uv[1] * side - 0.5
            j0, i0 = int(np.floor(s)), int(np.floor(t))
            fx, fy = s - j0, t - i0
            child = max(tap_level - PLANE_SPLIT_DEPTH, 0)
            block = 1 << (tap_level - child)
            image = maps.moments[child]
            for di, wy in ((0, 1.0 - fy), (1, fy)):
                for dj, wx in ((0, 1.0 - fx), (1, fx)):
                    i = min(max(i0 + di, 0), side - 1)
                    j = min(max(j0 + dj, 0), side - 1)
                    texels = image[i * block:(i + 1) * block, j * block:(j + 1) * block].reshape(-1, MOMENT_CHANNELS)
                    classes = normal_class(texels[:, CH_DIFFUSE_DIRECTION])
                    np.add.at(out[n], classes, (share * wy * wx / (block * block)) * texels)
    keep = np.zeros(MOMENT_CHANNELS)
    keep[_DIFFUSE_CHANNELS] = 1.0
    return out * keep


def split_planes(totals, class_totals):
    """(main (N, 20), extra (N, PLANE_SPLIT_EXTRA, 20)): each cluster's totals with the diffuse
    channels of its extra planes moved out, and those planes' totals (diffuse channels only; zero
    where unused). A cluster splits when :func:`normals_disagree` and at least two classes of
    ``class_totals`` (N, 6, 20, the scale of ``totals``) hold PLANE_SPLIT_SHARE of its diffuse
    power; the largest class stays, the next ones by power (ties by class) up to PLANE_SPLIT_EXTRA
    leave if they hold that share. The kernel's VSGL keeps the other classes' sum."""
    totals, class_totals = f64(totals).copy(), f64(class_totals)
    weight = luminance(class_totals[..., CH_DIFFUSE])  # (N, 6)
    order = np.argsort(-weight, axis=1, kind="stable")
    ranked = np.take_along_axis(weight, order, axis=1)
    major = (ranked >= PLANE_SPLIT_SHARE * weight.sum(axis=1, keepdims=True)) & (ranked > 0.0)
    split = normals_disagree(totals) & (major.sum(axis=1) >= 2)
    extra = np.zeros((len(totals), PLANE_SPLIT_EXTRA, MOMENT_CHANNELS))
    for n in np.flatnonzero(split):
        leaving = [c for c, keep in zip(order[n, 1:1 + PLANE_SPLIT_EXTRA], major[n, 1:1 + PLANE_SPLIT_EXTRA]) if keep]
        for e, c in enumerate(leaving):
            extra[n, e] = class_totals[n, c]
        staying = [c for c in range(NORMAL_CLASSES) if c not in leaving]
        totals[n, _DIFFUSE_CHANNELS] = class_totals[n, staying][:, _DIFFUSE_CHANNELS].sum(axis=0)
    return totals, extra


#: The GPU's table is one texture row (passes/vsgl_generation.MAX_VSGL_COUNT columns): a plane split
#: needs N (1 + PLANE_SPLIT_EXTRA) of them, so N above 4096 keeps 000's clusters.
PLANE_SPLIT_MAX_COLUMNS = 16384


def plane_split_applies(plane_split, kernel, vsgl_count) -> bool:
    """Whether a generation asked for ``plane_split`` splits: modified kernels only (the original
    kernels are 000's comparison baseline, the 2-VSGL mode has no kernels) and a table that fits
    (PLANE_SPLIT_MAX_COLUMNS)."""
    return bool(plane_split) and kernel == "modified" \
        and int(vsgl_count) * (1 + PLANE_SPLIT_EXTRA) <= PLANE_SPLIT_MAX_COLUMNS


def compact_plane_split(table: dict, kernel_count: int) -> dict:
    """The table without its unused extra-plane slots: the first ``kernel_count`` rows (one per
    kernel), then each slot with power (in slot order); ``rsm_total_power`` as it is."""
    power = np.asarray(table["power"]).reshape(len(table["power"]), -1)
    if len(power) <= kernel_count:
        return table
    keep = np.ones(len(power), bool)
    keep[kernel_count:] = np.any(power[kernel_count:] != 0.0, axis=1)
    return {name: (np.asarray(value)[keep] if name != "rsm_total_power" and np.ndim(value) and len(value) == len(keep)
                   else value) for name, value in table.items()}


def generate_vsgls(rsm, vsgl_count, k=1.0, kernel="modified", seed=0, pdf=None,
                   rotation=None, positional_distribution="per-lobe", split_at_jumps=None,
                   plane_split=None) -> dict:
    """Generate VSGLs from an RSM by filtered importance sampling (000 §4, app. B.3, app. D).

    rsm         an :class:`RSM` or a mapping with its field names.
    vsgl_count  N, the number of kernels (ignored by 'two-vsgl', which always returns 2).
    k           K > 0, the kernel-size parameter (000 Eq. 1 and §4.2: K/N in Eq. 3).
    kernel      'modified' (000 Eq. 3 + Eq. 5), 'original' (000 Eq. 1 + Eq. 4) or 'two-vsgl' (003).
    seed        seed of the random lattice rotation (None: no rotation); ignored if ``rotation``.
    pdf         (H, W) non-negative image, normalized here; default: lum(Φ (Rd + Rs)).
    rotation    explicit Cranley-Patterson shift (2,) of the Fibonacci lattice.
    positional_distribution  "per-lobe" (default) or "shared" (000 app. B.2 as written); see
                ``POSITIONAL_DISTRIBUTIONS`` and ``vsgl_parameters``.
    split_at_jumps  'modified' kernels over a depth discontinuity descend until they hold none
                of it (:func:`kernel_level_unstraddled`; SPLIT_AT_JUMPS when None).
    plane_split  clusters over several planes give each plane its own VSGL (PLANE_SPLIT when
                None; see there): the N kernels' VSGLs come first, then the extra planes' in
                kernel order (their kernel's centre and level); N rows without it.

    Returns a dict of float64 arrays, one row per VSGL: ``mean`` (N, 3), ``variance`` (N)
    (000 app. B.2), ``diffuse_mean``/``specular_mean`` (N, 3), ``diffuse_variance``/
    ``specular_variance`` (N) (the lobes' positions shading uses),
    ``diffuse_amplitude`` (N, 3), ``diffuse_axis`` (N, 3), ``diffuse_sharpness`` (N),
    ``specular_amplitude`` (N, 3), ``specular_axis`` (N, 3), ``specular_sharpness`` (N),
    ``power`` (N, 3) (the cluster's estimate of Σ Φ (Rd + Rs)), ``kernel_center`` (N, 2) in
    [0, 1]^2, ``kernel_level`` (N); and ``rsm_total_power`` (3), the exact Σ Φ (Rd + Rs).
    """
    if kernel not in KERNEL_MODES:
        raise ValueError(f"kernel must be one of {KERNEL_MODES}, got {kernel!r}")
    _check_positional_distribution(positional_distribution)
    rsm = RSM.coerce(rsm)
    if kernel == "two-vsgl":
        return two_vsgls(rsm)
    vsgl_count = int(vsgl_count)
    if vsgl_count < 1:
        raise ValueError(f"vsgl_count must be >= 1, got {vsgl_count}")
    k = float(k)
    if not (np.isfinite(k) and k > 0.0):
        raise ValueError(f"k must be finite and positive, got {k}")
    maps = build_mipmaps(rsm, pdf)

    lattice = mipmap.fibonacci_lattice(vsgl_count, lattice_rotation(seed, rotation))
    center, texel = mipmap.warp_hierarchical(maps.pdf, lattice)
    level, center, scale = _cluster_scale(maps, center, texel, k, vsgl_count, kernel, split_at_jumps)
    totals = mipmap.trilinear(maps.moments, center, level) * scale[:, None]

    fallback_mean, fallback_variance = _rsm_fallback(maps.moments[-1])
    plane_split = plane_split_applies(PLANE_SPLIT if plane_split is None else plane_split, kernel, vsgl_count)
    extra = np.zeros((vsgl_count, 0, MOMENT_CHANNELS))
    if plane_split:
        splits = normals_disagree(totals)
        class_totals = np.zeros((vsgl_count, NORMAL_CLASSES, MOMENT_CHANNELS))
        if splits.any():
            class_totals[splits] = plane_class_moments(maps, center[splits], level[splits]) * scale[splits, None, None]
        totals, extra = split_planes(totals, class_totals)
    rows = np.concatenate([totals, extra.reshape(-1, MOMENT_CHANNELS)])
    out = vsgl_parameters(rows, fallback_mean, fallback_variance, positional_distribution)
    parent = np.concatenate([np.arange(vsgl_count), np.repeat(np.arange(vsgl_count), extra.shape[1])])
    out["kernel_center"] = center[parent]
    out["kernel_level"] = level[parent]
    out["rsm_total_power"] = (rsm.flux_diffuse + rsm.flux_specular).reshape(-1, 3).sum(axis=0)
    return compact_plane_split(out, vsgl_count)
