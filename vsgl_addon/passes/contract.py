# SPDX-License-Identifier: GPL-3.0-or-later
"""What every GPU pass declares, so that warm-up, timings, statistics and a frame planner read one
list (``vsgl_addon.passes.PASSES``) instead of knowing each pass.

A pass module instantiates :class:`GPUPass` once, as ``PASS``: its shaders (create-info interface,
stage files, defines and layout code, see :mod:`vsgl_addon.shaders`), what it reads and writes
(the names of :data:`vsgl_addon.layouts.LAYOUTS` for the textures passes hand each other, "scene"
for the uploaded triangles, or the name of another image a pass makes, e.g. "rsm_depth"), the timed
:class:`Step` it runs in, and its ``run`` entry, whose result the pass's :meth:`GPUPass.free`
releases. Shaders are compiled on first
use and cached in the ``PASS`` for the process; objects made from them (a batch bound to a shader's
vertex format, a dummy texture) are cached with them and dropped by :meth:`GPUPass.free_shaders`.

Nothing here needs a GPU context until a shader is compiled.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from typing import Any, Callable, Mapping

from ..shaders import LIBRARY_DEFINES, ShaderInterface, create_shader


@dataclass(frozen=True)
class Step:
    """A timed step of a frame: ``name`` is its key in ``FrameImages.timings`` (the benchmark and
    the JSON report read these keys), ``label`` what the statistics panel shows; ``counts`` the
    entries of ``FrameImages.counts`` the step is the source of (key -> label)."""

    name: str
    label: str
    counts: Mapping[str, str] = field(default_factory=dict)


#: The light passes run as one timed step: the VSGL count is shared among a light's views by their
#: power, which needs each view's RSM before the next light's (pipeline.py).
LIGHT_PASSES = Step("rsm_and_vsgl_generation", "RSM + VSGL Generation",
                    {"rsm_views": "RSM Views", "vsgls": "VSGLs"})


@dataclass(frozen=True)
class ShaderSpec:
    """One shader of a pass: its create-info declarations and stage files (relative to glsl/).

    ``defines`` and ``code`` are called at compile time, so a shader built after a layout
    declaration changes (the layout tests patch one) follows it.
    """

    interface: Callable[[], ShaderInterface]
    stages: Mapping[str, str]  # "vertex" / "fragment" / "compute" -> file
    defines: Callable[[], dict] = dict
    code: Callable[[], dict] = dict  # stage ("fragment", "compute", ...) -> generated GLSL

    def compile(self, name: str):
        return create_shader(name, self.interface(), defines=self.defines(), code=self.code(),
                             **self.stages)


def _library_state() -> tuple:
    """The current defines of every library in shaders.LIBRARY_DEFINES (what a compiled shader
    requiring them was built with)."""
    return tuple((library, tuple(defines().items())) for library, defines in sorted(LIBRARY_DEFINES.items()))


def _free_result(result) -> None:
    if result is None:
        return
    if isinstance(result, (list, tuple)):
        for item in result:
            _free_result(item)
        return
    result.free()


@dataclass(frozen=True)
class GPUPass:
    """The contract of one GPU pass (see the module documentation)."""

    name: str  # the pass, and the prefix of its shaders' names
    label: str
    step: Step
    shaders: Mapping[str, ShaderSpec]
    reads: tuple[str, ...]
    writes: tuple[str, ...]
    run: Callable[..., Any]
    _cache: dict = field(default_factory=dict, compare=False, repr=False)

    def shader(self, key: str | None = None):
        """The compiled shader `key` (the pass's only one when None), cached for the process."""
        if key is None:
            (key,) = self.shaders
        # Compiled again when a library's defines changed since (a shader compiled before their
        # twin's value changed would disagree with the shaders compiled after it).
        state = _library_state()
        if key not in self._cache or self._cache.get(("library_state", key)) != state:
            shader_name = self.name if key == self.name else re.sub(r"\W", "_", f"{self.name}_{key}")
            self._cache[key] = self.shaders[key].compile(shader_name)
            self._cache[("library_state", key)] = state
        return self._cache[key]

    def resource(self, key: str, make: Callable[[], Any]):
        """An object made from the pass's shaders (e.g. a batch), cached and freed with them."""
        cache_key = ("resource", key)
        if cache_key not in self._cache:
            self._cache[cache_key] = make()
        return self._cache[cache_key]

    def compile_shaders(self) -> None:
        """Compile every shader now (keeps each stage's JIT out of the first frame)."""
        for key in self.shaders:
            self.shader(key)

    def free_shaders(self) -> None:
        """Drop the cached shaders and what was made from them (Blender frees GPU objects with their
        last reference)."""
        self._cache.clear()

    def free(self, result) -> None:
        """Release what :attr:`run` returned (an object with ``free()``, or a list of them)."""
        _free_result(result)


def run_stages(stages):
    """Run a staged build (a generator that yields between its parts and returns its result, as
    renderer.SceneLights.build_stages and ism.build_ism_atlas_stages) to its end; its result."""
    while True:
        try:
            next(stages)
        except StopIteration as done:
            return done.value
