# SPDX-License-Identifier: GPL-3.0-or-later
"""The render parameters as plain values (no bpy): what the passes receive, and every choice's table.

`scene.vsgl` (properties.py) stores them in the .blend; the command line overrides them for one
run. Ranges are the add-on's, shared by both (N from 1 to 4096, K from 0.25 to 16).

Every choice the user makes between techniques (kernel, lobe positions, what the overlay or a
look-dev image shows) is one :class:`Choices` table here, one :class:`Choice` per option. The
Blender enum items, the command line's ``choices``, the panels and the passes' validation are all
derived from it, so a new option (a PDF, a visibility technique) is one more row.

Paper references: 000 = Tokuyoshi, "Modified filtered importance sampling for virtual spherical
Gaussian lights" (CVM 2016); 003 = the Square Enix spherical Gaussian talk (2015).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace


@dataclass(frozen=True)
class Choice:
    """One option of a choice: what the passes, the .blend file and the user call it."""

    name: str  # what VSGLSettings, the passes and the command line use
    identifier: str  # the EnumProperty identifier stored in .blend files: never rename it
    label: str  # shown in the interface; free to change
    description: str  # the tooltip: what it does, what it costs, the paper's equation
    tag: str = ""  # short form in image names (operators.settings_image_name); "" = not used there
    ignores: tuple[str, ...] = ()  # scene.vsgl properties this option does not use (greyed out)


class Choices(tuple):
    """The options of one choice, in order. Blender stores an enum's value in the .blend as the
    option's position (its item number), so rows are only ever appended, never reordered."""

    def __new__(cls, *choices: Choice):
        for attribute in ("name", "identifier"):
            values = [getattr(choice, attribute) for choice in choices]
            if len(set(values)) != len(values):
                raise ValueError(f"duplicate {attribute} in {values}")
        return super().__new__(cls, choices)

    def __getnewargs__(self):  # copy and pickle call __new__ with the choices, not one tuple
        return tuple(self)

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(choice.name for choice in self)

    @property
    def identifiers(self) -> tuple[str, ...]:
        return tuple(choice.identifier for choice in self)

    def named(self, name: str) -> Choice:
        for choice in self:
            if choice.name == name:
                return choice
        raise KeyError(name)

    def identified(self, identifier: str) -> Choice:
        for choice in self:
            if choice.identifier == identifier:
                return choice
        raise KeyError(identifier)

    def number(self, name: str) -> int:
        """The option's position: its enum item number in the .blend (properties.enum_items), and
        for VIEWPORT_PASSES the display shader's `mode` (glsl/view/display.frag.glsl)."""
        return self.names.index(name)


#: How the reflective shadow map is clustered into VSGLs (000 Eq. 3; Eqs. 1, 4; 003).
KERNELS = Choices(
    Choice("modified", "MODIFIED", "Modified (Eq. 3)",
           "The paper's method (000 Eqs. 3, 5): each VSGL's kernel size is found by bisection on the "
           "mipmapped PDF, so a cluster's light and its PDF are filtered by the same kernel. "
           "Temporally stable; costs the same as Original within a few percent", tag="Modified"),
    Choice("original", "ORIGINAL", "Original (Eqs. 1, 4)",
           "Classic filtered importance sampling (Krivanek-Colbert, Tokuyoshi 2015): kernel size from "
           "the PDF at the kernel centre only. Kept for comparison: kernels overlap or leave gaps, "
           "which shows as flickering and errors with a changing, high-frequency PDF", tag="Original"),
    Choice("two-vsgl", "TWO_VSGL", "Two VSGLs (003)",
           "Simplified mode for a spot light on a local region (003): one diffuse and one specular VSGL "
           "summed over the whole reflective shadow map, with no mipmap and no sampling. Cheapest and "
           "flicker-free, but all bounce light comes from one blurred source; ignores VSGL Count and K",
           tag="TwoVSGL", ignores=("vsgl_count", "k", "positional_distribution")),
)

#: Which PDF VSGL generation samples the RSM with (000 §3-5; reference/brsm.py).
PDFS = Choices(
    Choice("light", "LIGHT", "Light (000 §4)",
           "Kernel centres follow each texel's bounce power lum(Φ(Rd + Rs)): VSGLs go where the light "
           "bounces, whether the camera sees that place or not"),
    Choice("view", "VIEW", "View (BRSM, 000 §5)",
           "Kernel centres follow the bounce power times each texel's importance to what the camera sees "
           "(its unshadowed form factor with a few hundred G-buffer samples), mixed with the light PDF "
           "(a quarter) so no lit texel is left out. Used for suns, whose map reaches far beyond the view "
           "(a sun over a large ground); other lights keep the light PDF. Costs a small G-buffer per frame "
           "and a GPU sum over texels × receivers per sun, and needs the frame's camera (the viewport "
           "keeps the light PDF)"),
)

#: Where each VSGL's two lobes sit (reference.vsgl explains both): each lobe's own power
#: centroid, or 000 app. B.2's one Gaussian for both.
POSITIONS = Choices(
    Choice("per-lobe", "PER_LOBE", "Per Lobe",
           "Each VSGL's diffuse and specular light sit at their own centre and spread (weighted by the "
           "diffuse, resp. specular power of its texels). Keeps a matte floor's bounce on the floor when a "
           "cluster also holds a shiny object's texels; costs the same to shade"),
    Choice("shared", "SHARED", "Shared (Paper)",
           "One position for both lobes, weighted by the total power, as the paper writes it (000 app. B.2, "
           "shared so one shadow map per VSGL serves both). Clusters mixing matte and shiny surfaces move "
           "one surface's bounce light towards the other"),
)

#: What the viewport overlay shows: the VIEWPORT_PASSES option of the same name, laid over the
#: viewport by coverage (overlay.view_pass_and_look); "added" is the indirect light added onto it.
OVERLAY_DISPLAYS = Choices(
    Choice("indirect", "INDIRECT", "Indirect Only",
           "One-bounce indirect light (diffuse + specular) alone, over black where there is geometry: "
           "shows exactly where the bounce light falls and how strong it is"),
    Choice("added", "ADDED", "Added to Viewport",
           "The indirect light added on top of whatever the viewport shows (solid, material preview, "
           "rendered): a quick look at the bounce light in context"),
    Choice("indirect_diffuse", "INDIRECT_DIFFUSE", "Indirect Diffuse",
           "Only the diffuse part of the indirect light (colour bleeding)"),
    Choice("indirect_specular", "INDIRECT_SPECULAR", "Indirect Specular",
           "Only the glossy part of the indirect light (glossy reflections of lit surfaces, caustics)"),
    Choice("direct", "DIRECT", "Direct",
           "Only the direct light the VSGL renderer computes (with its shadow-map shadows)"),
    Choice("combined", "COMBINED", "Combined",
           "Direct plus indirect light: what an F12 render with the VSGL engine gives"),
    Choice("indirect_caustics", "INDIRECT_CAUSTICS", "Indirect Caustics",
           "Only the caustics the glossy VPLs render (sharp reflectors' light on matte surfaces, 004; part "
           "of Indirect Diffuse); black where no lit sharp reflector exists"),
    Choice("indirect_glossy_reflectors", "INDIRECT_GLOSSY_REFLECTORS", "Indirect Glossy Reflectors",
           "Only the light sharp planar reflectors (rectangle proxies) send to glossy surfaces, as "
           "MRP-ASG renders it (001): the part of Indirect Specular that the VSGLs no longer carry"),
)

#: Which light a look-dev image holds (operators.py); the name is the renderer's FrameImages attribute.
LOOKDEV_PASSES = Choices(
    Choice("combined", "COMBINED", "Combined", "Direct plus one-bounce indirect light"),
    Choice("indirect", "INDIRECT", "Indirect", "One-bounce indirect light only (diffuse + specular)"),
    Choice("indirect_diffuse", "INDIRECT_DIFFUSE", "Indirect Diffuse", "Diffuse part of the indirect light"),
    Choice("indirect_specular", "INDIRECT_SPECULAR", "Indirect Specular", "Glossy part of the indirect light"),
    Choice("direct", "DIRECT", "Direct", "Direct light only"),
)

#: How MRP-ASG shades a receiver with a proxy's reflected light (001 Eq. 11, or Eq. 37's SG).
REFLECTOR_MODES = Choices(
    Choice("asg", "ASG", "ASG (Eq. 11)",
           "The paper's method (001 Eqs. 7, 11): the proxy's reflected light as an anisotropic SG, "
           "convolved with the receiver's NDF; keeps a reflection stretched at grazing angles"),
    Choice("sg", "SG", "SG (Eq. 37)",
           "Faster (001 Eq. 37): the reflected light as an isotropic SG of the ASG's larger bandwidth; "
           "loses the stretch of grazing reflections and some of their energy"),
)

#: Per object: whether its planar regions become rectangle proxies (vsgl_addon/proxies.py PROXY_MODES).
PROXY_OVERRIDES = Choices(
    Choice("auto", "AUTO", "Auto",
           "A planar region becomes a proxy when its material's GGX alpha is below Sharp Below"),
    Choice("always", "ALWAYS", "Always", "Every planar region of the object becomes a proxy, however rough"),
    Choice("never", "NEVER", "Never", "The object's light reaches glossy surfaces only through VSGLs"),
)

#: Which light the Rendered viewport shows (the VSGL engine's view_draw); the position is the
#: display shader's `mode` (glsl/view/display.frag.glsl). The same passes as F12's render result.
VIEWPORT_PASSES = Choices(
    Choice("combined", "COMBINED", "Combined", "Direct plus one-bounce indirect light, as F12 renders it"),
    Choice("direct", "DIRECT", "Direct", "Direct light only (the Direct render pass)"),
    Choice("indirect", "INDIRECT", "Indirect", "One-bounce indirect light only (the Indirect render pass)"),
    Choice("indirect_diffuse", "INDIRECT_DIFFUSE", "Indirect Diffuse",
           "Diffuse part of the indirect light (the Indirect Diffuse render pass)"),
    Choice("indirect_specular", "INDIRECT_SPECULAR", "Indirect Specular",
           "Glossy part of the indirect light (the Indirect Specular render pass)"),
    Choice("indirect_caustics", "INDIRECT_CAUSTICS", "Indirect Caustics",
           "The glossy VPLs' caustics alone (the Indirect Caustics render pass, part of Indirect Diffuse)"),
    Choice("indirect_glossy_reflectors", "INDIRECT_GLOSSY_REFLECTORS", "Indirect Glossy Reflectors",
           "The part of Indirect Specular that MRP-ASG renders: light of sharp planar reflectors on "
           "glossy surfaces (the Indirect Glossy Reflectors render pass)"),
)

#: The VPL pass's interleaved sampling (004 §6): N x N sub-images, each shading every N²-th VPL
#: (weighted N²), so a pixel costs 1/N² of the culled VPLs; the cross-bilateral filter removes the
#: pattern. "auto" picks N by resolution (settings.interleave_factor: 8 at 1080p as in 004).
INTERLEAVE_CHOICES = Choices(
    Choice("auto", "AUTO", "Auto",
           "By resolution: each sub-image keeps at least 1920x1080 / 64 pixels (N = 8 at 1080p, as in "
           "004 §6; 1 below about 0.14 megapixels)"),
    Choice("1", "N1", "1 x 1", "Every pixel shades every culled VPL: no pattern, the slowest"),
    Choice("2", "N2", "2 x 2", "Each pixel shades a quarter of the culled VPLs: about 4x faster, more noise"),
    Choice("4", "N4", "4 x 4", "Each pixel shades 1/16 of the culled VPLs: faster, noisier"),
    Choice("8", "N8", "8 x 8", "Each pixel shades 1/64 of the culled VPLs (004's 1080p choice): "
           "fastest, needs the filter"),
)

#: How the frame's quality is set: by hand, or from a target frame time (vsgl_addon/budget.py).
QUALITY_MODES = Choices(
    Choice("manual", "MANUAL", "Manual",
           "The settings below as they are: the frame takes what they cost"),
    Choice("budget", "BUDGET", "Budget",
           "A target frame time: VSGL count, RSM resolution, delta, VPL interleave and the resolution are "
           "chosen from a cost model of this machine (calibrated at first use, a few frames; kept in the "
           "user's cache), the passes as Auto weighs them, the rest as set below. The statistics show the "
           "predicted and measured time",
           ignores=("vsgl_count", "rsm_size", "delta_log10", "vpl_interleave")),
    Choice("auto", "AUTO", "Auto",
           "The settings below, but the frame planner leaves out the VPL pass or MRP-ASG where the share of "
           "the bounce its light path carries is small for the frame time the built-in cost model predicts "
           "it adds (the plan's reason says so); their light then comes from the VSGLs"),
)

KERNEL_MODES = KERNELS.names
POSITIONAL_DISTRIBUTIONS = POSITIONS.names

VSGL_COUNT_RANGE = (1, 4096)
K_RANGE = (0.25, 16.0)
# VSGL generation walks a square mip chain, so the RSM side is a power of two (1 x 1 works).
RSM_SIZE_RANGE = (1, 2048)
# Imperfect shadow maps (VSGL visibility): a power-of-two side (pull-push halves it), and the points
# splatted into each (one texture row of at most 16384).
ISM_SIZE_RANGE = (1, 256)
ISM_POINTS_RANGE = (1, 16384)
# MRP-ASG's sampling-disk radius in metres (001 §3.4) and the caustic roughness α_c (GGX α).
DISK_RADIUS_RANGE = (1e-4, 100.0)
CAUSTIC_ROUGHNESS_RANGE = (0.0, 1.0)
# Glossy VPLs (004): the acceptance threshold δ of Eq. 2 (log scale), the cross-bilateral filter's
# radius in pixels (004 uses 8) and the progressive VPL samples S (independent ξ draws averaged).
DELTA_RANGE = (1e-6, 1e-1)
VPL_FILTER_RADIUS_RANGE = (0, 16)
VPL_SAMPLES_RANGE = (1, 256)
# Budget mode's target frame time in milliseconds.
TIME_BUDGET_RANGE = (1.0, 600000.0)
#: Pixels per interleaved sub-image the automatic factor keeps (004 §6: N = 8 at 1920 x 1080).
INTERLEAVE_SUBIMAGE_PIXELS = 1920 * 1080 // 64


def delta_from_log10(exponent: float) -> float:
    """δ from the panel's log10 control (a float32 property): six significant digits, so a δ the
    command line set comes back as typed, kept inside DELTA_RANGE."""
    return min(max(float(f"{10.0 ** float(exponent):.6g}"), DELTA_RANGE[0]), DELTA_RANGE[1])


def interleave_factor(choice: str, width: int, height: int) -> int:
    """N of the VPL pass's N x N interleaving: the chosen one, or for "auto" the largest of 1, 2, 4, 8
    whose sub-images keep INTERLEAVE_SUBIMAGE_PIXELS each (8 at 1080p, 1 at 480 x 270)."""
    if choice != "auto":
        return int(INTERLEAVE_CHOICES.named(choice).name)
    pixels = max(int(width), 1) * max(int(height), 1)
    factor = 1
    for n in (2, 4, 8):
        if pixels >= n * n * INTERLEAVE_SUBIMAGE_PIXELS:
            factor = n
    return factor


class SettingsError(ValueError):
    """A parameter outside its range; the message names it, the range and the value."""


def _check_range(name, value, low, high):
    if not (low <= value <= high):
        raise SettingsError(f"{name} must be in [{low:g}, {high:g}], got {value:g}")


def nearest_power_of_two(size: int, size_range=RSM_SIZE_RANGE) -> int:
    """The power of two nearest to `size` in log scale, within `size_range` (the RSM's by default)."""
    size = min(max(int(size), size_range[0]), size_range[1])
    return 2 ** round(math.log2(size))


@dataclass(frozen=True)
class VSGLSettings:
    vsgl_count: int = 256
    k: float = 1.0
    kernel: str = "modified"
    rsm_size: int = 128
    seed: int = 0
    positional_distribution: str = "per-lobe"
    # VSGL visibility (000 §5: a 64² imperfect shadow map per VSGL): on, the map side, and the
    # scene points splatted into each map. On by default: on the validation suite it halves the
    # error where an occluder stands between bounce and receiver and costs enclosed rooms a few
    # per cent of their light (benchmarks/results/validation_suite.md); off reproduces the images
    # without it exactly.
    visibility: bool = True
    ism_size: int = 64
    ism_points: int = 4096
    # Glossy reflectors (001, MRP-ASG): on wherever a rectangle proxy exists; the sampling disk's
    # radius r_d in metres (docs/accuracy.md: the sweep it was chosen from), α_c (GGX α below which
    # a planar reflector becomes a proxy) and the shading mode.
    glossy_reflectors: bool = True
    disk_radius: float = 0.1
    caustic_roughness: float = 0.1
    reflector_mode: str = "asg"
    # Glossy VPLs (004): on wherever a lit reflector's GGX α is below caustic_roughness (the same
    # α_c as MRP-ASG's proxies; light-paths.md), δ, the interleave choice, filter radius, samples S.
    caustics: bool = True
    delta: float = 1e-3
    vpl_interleave: str = "auto"
    vpl_filter_radius: int = 8
    vpl_samples: int = 1
    # The VPLs' shadows (one imperfect shadow map per cluster of VPLs, with visibility on): on by
    # default. Against ray casting they take the error of an occluded caustic from 1.97 to 1.05
    # (benchmarks/results/vpl_visibility.md); on the validation suite no scene's relative RMSE is
    # worse than with them off (polished_metal_floor 1.383 -> 1.373, the others equal).
    vpl_visibility: bool = True
    # VSGL generation's PDF (PDFS): the view-dependent one (000 §5), the default, which the planner
    # gives the suns' kernels only (planner.VIEW_PDF_LIGHT_TYPES: their RSM reaches far beyond the
    # view), or the light's (000 §4) for every light. On the suite's sun scenes it takes the relative
    # RMSE 16 % (courtyard) and 67 % (open ground) down at the light PDF's means
    # (benchmarks/results/view_pdf.md).
    pdf: str = "view"
    # Quality mode (QUALITY_MODES) and Budget mode's target frame time in ms (vsgl_addon/budget.py).
    quality_mode: str = "manual"
    time_budget_ms: float = 100.0

    def __post_init__(self):
        _check_range("VSGL count", self.vsgl_count, *VSGL_COUNT_RANGE)
        if not math.isfinite(self.k):
            raise SettingsError(f"K must be a finite number, got {self.k}")
        _check_range("K", self.k, *K_RANGE)
        if self.kernel not in KERNEL_MODES:
            raise SettingsError(f"kernel must be one of {', '.join(KERNEL_MODES)}, got {self.kernel!r}")
        _check_range("RSM size", self.rsm_size, *RSM_SIZE_RANGE)
        if self.rsm_size & (self.rsm_size - 1):
            raise SettingsError(f"RSM size must be a power of two, got {self.rsm_size}")
        if self.seed < 0:
            raise SettingsError(f"seed must be 0 or more, got {self.seed}")
        if self.positional_distribution not in POSITIONAL_DISTRIBUTIONS:
            raise SettingsError(f"positional distribution must be one of "
                                f"{', '.join(POSITIONAL_DISTRIBUTIONS)}, got {self.positional_distribution!r}")
        _check_range("ISM size", self.ism_size, *ISM_SIZE_RANGE)
        if self.ism_size & (self.ism_size - 1):
            raise SettingsError(f"ISM size must be a power of two, got {self.ism_size}")
        _check_range("points per ISM", self.ism_points, *ISM_POINTS_RANGE)
        if not (math.isfinite(self.disk_radius) and math.isfinite(self.caustic_roughness)):
            raise SettingsError("disk radius and caustic roughness must be finite numbers")
        _check_range("disk radius", self.disk_radius, *DISK_RADIUS_RANGE)
        _check_range("caustic roughness", self.caustic_roughness, *CAUSTIC_ROUGHNESS_RANGE)
        if self.pdf not in PDFS.names:
            raise SettingsError(f"PDF must be one of {', '.join(PDFS.names)}, got {self.pdf!r}")
        if self.reflector_mode not in REFLECTOR_MODES.names:
            raise SettingsError(f"reflector mode must be one of {', '.join(REFLECTOR_MODES.names)}, "
                                f"got {self.reflector_mode!r}")
        if not math.isfinite(self.delta):
            raise SettingsError(f"delta must be a finite number, got {self.delta}")
        _check_range("delta", self.delta, *DELTA_RANGE)
        if self.vpl_interleave not in INTERLEAVE_CHOICES.names:
            raise SettingsError(f"VPL interleave must be one of {', '.join(INTERLEAVE_CHOICES.names)}, "
                                f"got {self.vpl_interleave!r}")
        _check_range("VPL filter radius", self.vpl_filter_radius, *VPL_FILTER_RADIUS_RANGE)
        _check_range("VPL samples", self.vpl_samples, *VPL_SAMPLES_RANGE)
        if self.quality_mode not in QUALITY_MODES.names:
            raise SettingsError(f"quality mode must be one of {', '.join(QUALITY_MODES.names)}, "
                                f"got {self.quality_mode!r}")
        if not math.isfinite(self.time_budget_ms):
            raise SettingsError(f"time budget must be a finite number, got {self.time_budget_ms}")
        _check_range("time budget (ms)", self.time_budget_ms, *TIME_BUDGET_RANGE)

    @classmethod
    def from_properties(cls, properties) -> "VSGLSettings":
        """From a `scene.vsgl` property group (or anything with its attribute names).

        The property allows any RSM resolution in its range; the passes use the nearest power of two.
        """
        return cls(vsgl_count=int(properties.vsgl_count), k=float(properties.k),
                   kernel=KERNELS.identified(properties.kernel).name,
                   rsm_size=nearest_power_of_two(properties.rsm_size), seed=int(properties.seed),
                   positional_distribution=POSITIONS.identified(properties.positional_distribution).name,
                   visibility=bool(getattr(properties, "visibility", True)),
                   ism_size=nearest_power_of_two(getattr(properties, "ism_size", 64), ISM_SIZE_RANGE),
                   ism_points=int(getattr(properties, "ism_points", 4096)),
                   glossy_reflectors=bool(getattr(properties, "glossy_reflectors", True)),
                   disk_radius=float(getattr(properties, "disk_radius", 0.1)),
                   caustic_roughness=float(getattr(properties, "caustic_roughness", 0.1)),
                   reflector_mode=REFLECTOR_MODES.identified(getattr(properties, "reflector_mode", "ASG")).name,
                   caustics=bool(getattr(properties, "caustics", True)),
                   delta=delta_from_log10(float(getattr(properties, "delta_log10", -3.0))),
                   vpl_interleave=INTERLEAVE_CHOICES.identified(getattr(properties, "vpl_interleave", "AUTO")).name,
                   vpl_filter_radius=int(getattr(properties, "vpl_filter_radius", 8)),
                   vpl_samples=int(getattr(properties, "vpl_samples", 1)),
                   vpl_visibility=bool(getattr(properties, "vpl_visibility", True)),
                   pdf=PDFS.identified(getattr(properties, "pdf", "LIGHT")).name,
                   quality_mode=QUALITY_MODES.identified(getattr(properties, "quality_mode", "MANUAL")).name,
                   time_budget_ms=float(getattr(properties, "time_budget_ms", 100.0)))

    def overridden(self, **values) -> "VSGLSettings":
        """A copy with the given values (None means keep), validated."""
        return replace(self, **{name: value for name, value in values.items() if value is not None})
