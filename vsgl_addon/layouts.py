# SPDX-License-Identifier: GPL-3.0-or-later
"""The texture layouts the GPU passes hand each other, declared once.

A layout is an ordered list of **slots**, each one RGBA32F texel: the rows of one table texture
(the VSGL table: column i = VSGL i) or the colour attachments of one framebuffer (the RSM, the
camera G-buffer, the shading inputs). A slot lists the fields it holds, filling its four channels in order; a field may
spread over several slots (the kernel centre's u and v). Everything else is derived from here:

* Python packs and unpacks numpy arrays with :meth:`TextureLayout.pack` / :meth:`TextureLayout.unpack`
  (tables) and :meth:`TextureLayout.unpack_slots` (attachments read back);
* GLSL receives the slot indices as defines (``VSGL_ROW_DIFFUSE_LOBE``: :meth:`TextureLayout.defines`)
  and generated code (:meth:`TextureLayout.glsl`): a struct with one member per field, a pack and an
  unpack function per slot, and the store / load of a whole record (``imageStore`` / ``texelFetch``
  of every row, or the fragment outputs / samplers named ``<prefix><slot>``). Shaders name fields,
  never a row or a channel, so reordering slots here reorders every reader and writer.

The meaning of each field (and the paper it comes from) is documented where it is computed: the VSGL
table in ``passes/vsgl_generation.py`` (000 §3-4, app. B), the RSM in ``passes/rsm.py`` (000 §4),
the G-buffer in ``passes/gbuffer.py``, the shading inputs in ``passes/shading_inputs.py``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

_GLSL_TYPES = {1: "float", 2: "vec2", 3: "vec3", 4: "vec4"}
_COMPONENTS = "xyzw"


def _fetch(access: str, texture: str, texel: str) -> str:
    """GLSL reading one texel of `texture` (a sampler, or an image for the ``image*`` accesses)."""
    return f"imageLoad({texture}, {texel})" if access.startswith("image") else f"texelFetch({texture}, {texel}, 0)"


@dataclass(frozen=True)
class Slot:
    """One RGBA texel of a layout: (field, component count) entries filling channels 0, 1, ..."""

    name: str
    fields: tuple[tuple[str, int], ...]
    per_table: bool = False  # a table row written once, in column 0 (not per record)

    def __post_init__(self):
        if sum(count for _, count in self.fields) > 4:
            raise ValueError(f"slot {self.name!r} holds more than four channels")


@dataclass(frozen=True)
class TextureLayout:
    """An ordered list of slots (see the module documentation).

    ``define_prefix`` names the slot-index defines (``VSGL_ROW`` -> ``VSGL_ROW_POWER``),
    ``glsl_prefix`` the generated functions and the samplers / outputs / image (``vsgl_table``),
    ``struct`` the generated GLSL struct. ``integer_fields`` are stored as floats and read back as
    int64.
    """

    name: str
    slots: tuple[Slot, ...]
    define_prefix: str
    glsl_prefix: str
    struct: str
    integer_fields: frozenset = field(default_factory=frozenset)

    # --- Declaration queries -------------------------------------------------------------------

    @property
    def slot_names(self) -> tuple[str, ...]:
        return tuple(slot.name for slot in self.slots)

    def index(self, slot: str) -> int:
        return self.slot_names.index(slot)

    def _derived(self) -> tuple:
        """(placements, field widths, per-table fields) of the current ``slots``, computed once per
        slots tuple: every RSM view's constants and every VSGL table read back go through pack /
        unpack, a few hundred calls a frame with many lights. Keyed by the tuple itself, so a
        layout whose ``slots`` is replaced (tests reorder declarations) derives them again."""
        cached = self.__dict__.get("_derived_cache")
        if cached is not None and cached[0] is self.slots:
            return cached[1]
        used: dict[str, int] = {}
        entries = []
        widths: dict[str, int] = {}
        for index, slot in enumerate(self.slots):
            channel = 0
            for name, count in slot.fields:
                entries.append((index, channel, name, used.get(name, 0), count))
                used[name] = used.get(name, 0) + count
                widths[name] = widths.get(name, 0) + count
                channel += count
        per_table = tuple(name for slot in self.slots if slot.per_table for name, _ in slot.fields)
        derived = (tuple(entries), widths, per_table)
        object.__setattr__(self, "_derived_cache", (self.slots, derived))
        return derived

    def _placements(self):
        """(slot index, channel, field, first component of the field, count) of every entry."""
        return iter(self._derived()[0])

    @property
    def _field_widths(self) -> dict[str, int]:
        return self._derived()[1]

    @property
    def fields(self) -> dict[str, int]:
        """Field name -> component count, in order of first appearance."""
        return dict(self._field_widths)

    def per_table_fields(self) -> tuple[str, ...]:
        return self._derived()[2]

    def record_fields(self) -> tuple[str, ...]:
        per_table = set(self.per_table_fields())
        return tuple(name for name in self._field_widths if name not in per_table)

    def field_shape(self, name: str) -> tuple[int, ...]:
        width = self._field_widths[name]
        return () if width == 1 else (width,)

    def defines(self) -> dict[str, int]:
        """``<define_prefix>_<SLOT>`` = slot index, and ``<define_prefix>_COUNT``."""
        out = {f"{self.define_prefix}_{slot.name.upper()}": index for index, slot in enumerate(self.slots)}
        out[f"{self.define_prefix}_COUNT"] = len(self.slots)
        return out

    # --- numpy ---------------------------------------------------------------------------------

    def _read(self, texels, names=None) -> dict[str, np.ndarray]:
        """Fields (all, or `names`) from the texel arrays of the slots (index -> (..., 4)), float64
        (int64 for integer fields)."""
        parts: dict[str, list[np.ndarray]] = {}
        for index, channel, name, _, count in self._placements():
            if names is None or name in names:
                parts.setdefault(name, []).append(texels[index][..., channel:channel + count])
        out = {}
        for name, pieces in parts.items():
            value = np.concatenate(pieces, axis=-1).astype(np.float64)
            if value.shape[-1] == 1:
                value = value[..., 0]
            out[name] = value.astype(np.int64) if name in self.integer_fields else value
        return out

    def unpack(self, table: np.ndarray, count: int) -> dict[str, np.ndarray]:
        """A read-back table (slots, width, 4) -> fields: records of columns [0, count), per-table
        fields from column 0."""
        table = np.asarray(table)
        per_table = set(self.per_table_fields())
        records = self._read([table[index, :count] for index in range(len(self.slots))])
        firsts = self._read([table[index, 0] for index in range(len(self.slots))])
        return {name: firsts[name] if name in per_table else records[name] for name in self._field_widths}

    def pack(self, values, count: int, width: int | None = None) -> np.ndarray:
        """(slots, max(width, count, 1), 4) float32 table of the fields `values` has (others 0)."""
        table = np.zeros((len(self.slots), max(width or 0, count, 1), 4), dtype=np.float32)
        per_table = set(self.per_table_fields())
        for index, channel, name, first, number in self._placements():
            if name not in values:
                continue
            value = np.asarray(values[name], dtype=np.float64)
            value = value.reshape(value.shape + (1,)) if self._field_widths[name] == 1 else value
            if name in per_table:
                table[index, 0, channel:channel + number] = value[first:first + number]
            elif count:
                table[index, :count, channel:channel + number] = value[:count, first:first + number]
        return table

    def pack_slots(self, values, shape) -> dict[str, np.ndarray]:
        """Slot name -> (*shape, 4) float32 texels of the fields `values` has (others 0), e.g. the
        attachments of an RSM made in numpy."""
        out = {name: np.zeros(tuple(shape) + (4,), dtype=np.float32) for name in self.slot_names}
        for index, channel, name, first, number in self._placements():
            if name not in values:
                continue
            value = np.asarray(values[name])
            value = value[..., None] if self._field_widths[name] == 1 else value[..., first:first + number]
            out[self.slots[index].name][..., channel:channel + number] = value
        return out

    def unpack_slots(self, texels, names=None) -> dict[str, np.ndarray]:
        """Attachments read back (slot name -> (..., 4) array) -> fields (all, or those `names`)."""
        wanted = None if names is None else set(names)
        needed = {index for index, _, name, _, _ in self._placements() if wanted is None or name in wanted}
        return self._read({index: np.asarray(texels[self.slots[index].name]) for index in needed}, wanted)

    # --- GLSL ----------------------------------------------------------------------------------

    def _member(self, name: str, first: int, count: int) -> str:
        if self._field_widths[name] == count:
            return f"r.{name}"
        return f"r.{name}.{_COMPONENTS[first:first + count]}"

    def glsl(self, access: str | None = None) -> str:
        """GLSL declarations of the layout: the slot defines, the struct, per-slot pack / unpack, and
        for `access`:

        * ``"image_store"``: ``void <prefix>_store(int column, <struct> r)`` writes every record row
          of the image ``<prefix>`` (per-table rows are stored by the caller with the pack function);
        * ``"sampler_load"``: ``<struct> <prefix>_load(int column)`` fetches every record row of the
          sampler ``<prefix>``;
        * ``"outputs_store"``: ``void <prefix>_store(<struct> r)`` writes the fragment outputs
          ``<prefix>_<slot>``;
        * ``"samplers_load"``: ``<struct> <prefix>_load(ivec2 texel)`` fetches the samplers
          ``<prefix>_<slot>``;
        * ``"image_load"`` / ``"images_load"``: the same loads from RGBA32F images of those names
          (``imageLoad``: the same texels; on llvmpipe it costs a fraction of a ``texelFetch``,
          benchmarks/results/light_build_profile.md).
        """
        prefix = self.glsl_prefix
        lines = [f"#define {name} {value}" for name, value in self.defines().items()]
        lines.append(f"struct {self.struct} {{")
        lines += [f"  {_GLSL_TYPES[width]} {name};" for name, width in self.fields.items()]
        lines.append("};")
        placements = list(self._placements())
        for index, slot in enumerate(self.slots):
            entries = [p for p in placements if p[0] == index]
            members = [self._member(name, first, count) for _, _, name, first, count in entries]
            padding = 4 - sum(count for *_, count in entries)
            members += ["0.0"] * padding
            lines.append(f"vec4 {prefix}_pack_{slot.name}({self.struct} r)")
            lines.append(f"{{\n  return vec4({', '.join(members)});\n}}")
            lines.append(f"void {prefix}_unpack_{slot.name}(vec4 texel, inout {self.struct} r)")
            body = [f"  {self._member(name, first, count)} = texel.{_COMPONENTS[channel:channel + count]};"
                    for _, channel, name, first, count in entries]
            lines.append("{\n" + "\n".join(body) + "\n}")
        records = [slot for slot in self.slots if not slot.per_table]
        if access == "image_store":
            lines.append(f"void {prefix}_store(int column, {self.struct} r)\n{{")
            lines += [f"  imageStore({prefix}, ivec2(column, {self.index(slot.name)}), {prefix}_pack_{slot.name}(r));"
                      for slot in records]
            lines.append("}")
        elif access in ("sampler_load", "image_load"):
            lines.append(f"{self.struct} {prefix}_load(int column)\n{{\n  {self.struct} r;")
            lines += [f"  {prefix}_unpack_{slot.name}({_fetch(access, prefix, f'ivec2(column, {self.index(slot.name)})')}, r);"
                      for slot in records]
            lines.append("  return r;\n}")
        elif access == "outputs_store":
            lines.append(f"void {prefix}_store({self.struct} r)\n{{")
            lines += [f"  {prefix}_{slot.name} = {prefix}_pack_{slot.name}(r);" for slot in records]
            lines.append("}")
        elif access in ("samplers_load", "images_load"):
            lines.append(f"{self.struct} {prefix}_load(ivec2 texel)\n{{\n  {self.struct} r;")
            lines += [f"  {prefix}_unpack_{slot.name}({_fetch(access, f'{prefix}_{slot.name}', 'texel')}, r);"
                      for slot in records]
            lines.append("  return r;\n}")
        elif access is not None:
            raise ValueError(f"unknown layout access {access!r}")
        return "\n".join(lines) + "\n"


#: The VSGL table (RGBA32F, count x rows; column i = VSGL i), written by VSGL generation and read
#: by VSGL shading and the export. shared_position is 000 app. B.2's Gaussian (weight Φ(Rd + Rs));
#: diffuse_position / specular_position each lobe's own (the positional distribution);
#: kernel_texel the level-0 texel (row, column) the warp chose.
VSGL_TABLE = TextureLayout(
    name="vsgl_table",
    slots=(
        Slot("shared_position", (("mean", 3), ("variance", 1))),
        Slot("diffuse_lobe", (("diffuse_amplitude", 3), ("diffuse_sharpness", 1))),
        Slot("diffuse_axis", (("diffuse_axis", 3), ("kernel_level", 1))),
        Slot("specular_lobe", (("specular_amplitude", 3), ("specular_sharpness", 1))),
        Slot("specular_axis", (("specular_axis", 3), ("kernel_center", 1))),
        Slot("power", (("power", 3), ("kernel_center", 1))),
        Slot("kernel_texel", (("kernel_texel", 2),)),
        Slot("rsm_total_power", (("rsm_total_power", 3),), per_table=True),
        Slot("diffuse_position", (("diffuse_mean", 3), ("diffuse_variance", 1))),
        Slot("specular_position", (("specular_mean", 3), ("specular_variance", 1))),
    ),
    define_prefix="VSGL_ROW",
    glsl_prefix="vsgl_table",
    struct="VSGLRecord",
    integer_fields=frozenset({"kernel_texel"}),
)

#: The RSM's colour attachments (000 §4): one VPL per texel. specular_sharpness is λs of the
#: warped specular lobe, flux_white Φ₁ (the texel flux of a white light), texel_measure its solid
#: angle (or area for a sun), coverage 1 where the texel sees geometry.
RSM = TextureLayout(
    name="rsm",
    slots=(
        Slot("position", (("position", 3), ("specular_sharpness", 1))),
        Slot("normal", (("normal", 3), ("roughness", 1))),
        Slot("flux_diffuse", (("flux_diffuse", 3), ("flux_white", 1))),
        Slot("flux_specular", (("flux_specular", 3), ("texel_measure", 1))),
        Slot("specular_axis", (("specular_axis", 3), ("coverage", 1))),
    ),
    define_prefix="RSM_ATTACHMENT",
    glsl_prefix="rsm",
    struct="RSMTexel",
)

#: The camera G-buffer's colour attachments: Principled inputs per pixel (roughness perceptual);
#: object_index: SceneDescription.object_names' index of the object seen (light linking).
GBUFFER = TextureLayout(
    name="gbuffer",
    slots=(
        Slot("position", (("position", 3), ("coverage", 1))),
        Slot("normal", (("normal", 3), ("roughness", 1))),
        Slot("base_color", (("base_color", 3), ("metallic", 1))),
        Slot("material", (("specular_ior_level", 1), ("ior", 1), ("material_index", 1),
                          ("object_index", 1))),
    ),
    define_prefix="GBUFFER_ATTACHMENT",
    glsl_prefix="gbuffer",
    struct="GBufferTexel",
)

#: The shading inputs pass's outputs per camera pixel: Rd and the Schlick F0 of 000 app. C's
#: C(ξin); each alpha is 1 where the pixel has geometry.
SHADING_INPUTS = TextureLayout(
    name="shading_inputs",
    slots=(
        Slot("diffuse_reflectance", (("diffuse_reflectance", 3), ("diffuse_coverage", 1))),
        Slot("specular_f0", (("specular_f0", 3), ("specular_coverage", 1))),
    ),
    define_prefix="SHADING_INPUT",
    glsl_prefix="shading_inputs",
    struct="ShadingInputs",
)

#: The per-view constants of the RSM pass (a one-column table: push constants stay within the
#: 128 bytes every backend guarantees): the rows of the 3x3 view -> world rotation, the rows of the
#: inverse of the light's 3x3 world matrix (scale included), and the light's position, unit axis
#: (where it points), parameters (glsl/lib/lights.glsl) and colour.
RSM_VIEW = TextureLayout(
    name="rsm_view",
    slots=tuple(Slot(name, ((name, 3),)) for name in (
        "view_to_world_row0", "view_to_world_row1", "view_to_world_row2",
        "world_to_local_row0", "world_to_local_row1", "world_to_local_row2",
        "light_position", "light_axis")) + (
        Slot("light_params", (("light_params", 4),)),
        Slot("light_color", (("light_color", 3), ("sharp_alpha", 1))),
        Slot("light_links", (("light_factors", 2), ("light_index", 1), ("light_links_rows", 1))),
    ),
    define_prefix="RSM_VIEW_ROW",
    glsl_prefix="view_constants",
    struct="RSMViewConstants",
)

#: The rectangle proxies (001 §3.6; vsgl_addon/proxies.py) one light reaches, column i = proxy i:
#: read by the MRP-ASG pass (passes/mrp_asg.py) and by the RSM, whose VSGLs for the receivers'
#: glossy lobes leave out the proxies' specular flux (light-paths.md). alpha is GGX α,
#: f0 Schlick F0 (RGB), roughness the material's Principled roughness (the RSM's test of a texel).
PROXY_TABLE = TextureLayout(
    name="proxy_table",
    slots=(
        Slot("center", (("center", 3), ("half_u", 1))),
        Slot("normal", (("normal", 3), ("half_v", 1))),
        Slot("axis_u", (("axis_u", 3), ("alpha", 1))),
        Slot("axis_v", (("axis_v", 3), ("roughness", 1))),
        Slot("f0", (("f0", 3),)),
    ),
    define_prefix="PROXY_ROW",
    glsl_prefix="proxy_table",
    struct="ProxyRecord",
)

#: Every layout by name (the names passes declare in ``GPUPass.reads`` / ``writes``).
LAYOUTS = {layout.name: layout for layout in (VSGL_TABLE, RSM, GBUFFER, SHADING_INPUTS, RSM_VIEW, PROXY_TABLE)}
