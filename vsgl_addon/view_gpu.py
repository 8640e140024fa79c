# SPDX-License-Identifier: GPL-3.0-or-later
"""The GPU side of the view pipeline (view_pipeline.py): view renders as textures, their joint
bilateral upsampling into a viewport's accumulation images, and the draw of those images.

Everything stays on the GPU: a view render's textures (renderer.FrameRenderer.render_view_textures)
are resampled by ``glsl/view/resolve.frag.glsl`` (``glsl/lib/bilateral.glsl``, guided by the
full-resolution G-buffer) straight into RGBA32F accumulation textures, finished samples are added by
blending (``glsl/view/accumulate.frag.glsl``), and ``glsl/view/display.frag.glsl`` draws the average
into the bound framebuffer. No image is read back or uploaded per update
(``passes.gpu_util.RoundTrips`` counts them); one texel is read per step only to wait for the GPU
(``RoundTrips.syncs``), so a step's measured time is its own, and a coarse image reads one more
after its view passes, whose time alone sizes the next one.

Never touches bpy.context. Needs a GPU context, main thread.
"""

from __future__ import annotations

import atexit
from types import SimpleNamespace

import numpy as np

from .passes.contract import GPUPass, ShaderSpec, Step
from .passes.gpu_util import finish, fullscreen_triangle_batch
from .settings import VIEWPORT_PASSES
from .shaders import ShaderInterface

#: The accumulation images of a view (RGBA32F; rgb radiance sum, a coverage sum). The last two are
#: parts of indirect_diffuse (the glossy VPLs' caustics) and of indirect_specular (MRP-ASG's Indirect
#: Glossy Reflectors), kept apart only to be shown alone.
IMAGES = ("direct", "indirect_diffuse", "indirect_specular", "indirect_caustics", "indirect_glossy_reflectors")
#: Joint bilateral range parameters: positions compared in low-resolution texel footprints, and the
#: power of the normals' cosine (reference/bilateral.py has the same defaults).
SIGMA_POSITION = 1.0
NORMAL_POWER = 8.0

_OUTPUTS = [("VEC4", f"out_{name}") for name in IMAGES]
#: The view render's textures the resolve reads (renderer.ViewTextures; indirect_caustics only when
#: the glossy VPL pass ran, indirect_glossy_reflectors only when a proxy is lit, else a black texel).
LOW_IMAGES = ("direct_diffuse", "direct_specular", "indirect_diffuse", "indirect_specular", "indirect_caustics",
              "indirect_glossy_reflectors", "position", "normal")


def _resolve_interface() -> ShaderInterface:
    return ShaderInterface(
        push_constants=[("VEC4", "camera"), ("FLOAT", "projection_11"), ("FLOAT", "sigma_position"),
                        ("FLOAT", "normal_power"), ("FLOAT", "weight")],
        # The render's textures, read texel by texel four to sixteen times per pixel, as images: on
        # llvmpipe an imageLoad costs a fraction of a texelFetch (benchmarks/results/
        # view_passes_profile.md). Blender binds at most 8 images per shader, so the guides, read
        # once per pixel, stay samplers.
        images=[("RGBA32F", "FLOAT_2D", f"low_{name}") for name in LOW_IMAGES],
        samplers=[("FLOAT_2D", "guide_position"), ("FLOAT_2D", "guide_normal")],
        vertex_inputs=[("VEC2", "position")], varyings=[("VEC2", "uv")], fragment_outputs=_OUTPUTS)


#: What jbu_weights.frag.glsl writes per guide pixel (RGBA32F): (base texel x, y, weight sum,
#: coverage) and the four texels' weights.
WEIGHT_IMAGES = ("taps", "weights")


def _weights_interface() -> ShaderInterface:
    return ShaderInterface(
        push_constants=[("VEC4", "camera"), ("FLOAT", "projection_11"), ("FLOAT", "sigma_position"),
                        ("FLOAT", "normal_power")],
        images=[("RGBA32F", "FLOAT_2D", "low_position"), ("RGBA32F", "FLOAT_2D", "low_normal")],
        samplers=[("FLOAT_2D", "guide_position"), ("FLOAT_2D", "guide_normal")],
        vertex_inputs=[("VEC2", "position")], varyings=[("VEC2", "uv")],
        fragment_outputs=[("VEC4", f"out_{name}") for name in WEIGHT_IMAGES])


def _resolve_weighted_interface() -> ShaderInterface:
    # The render's six images and the kept weights: Blender's limit of 8 images, all read as images.
    return ShaderInterface(
        push_constants=[("FLOAT", "weight")],
        images=[("RGBA32F", "FLOAT_2D", f"low_{name}") for name in LOW_IMAGES[:6]]
        + [("RGBA32F", "FLOAT_2D", name) for name in WEIGHT_IMAGES],
        vertex_inputs=[("VEC2", "position")], varyings=[("VEC2", "uv")], fragment_outputs=_OUTPUTS)


def _accumulate_interface() -> ShaderInterface:
    # One texel of each image per pixel, read as images (an imageLoad costs less than a texelFetch
    # on llvmpipe; see _resolve_interface).
    return ShaderInterface(push_constants=[("FLOAT", "weight")],
                           images=[("RGBA32F", "FLOAT_2D", f"source_{name}") for name in IMAGES],
                           vertex_inputs=[("VEC2", "position")], varyings=[("VEC2", "uv")],
                           fragment_outputs=_OUTPUTS)


def _display_interface() -> ShaderInterface:
    return ShaderInterface(push_constants=[("INT", "mode"), ("FLOAT", "weight"), ("INT", "composition"),
                                           ("FLOAT", "scale"), ("FLOAT", "gamma"), ("INT", "encode_srgb")],
                           samplers=[("FLOAT_2D", f"accum_{name}") for name in IMAGES],
                           vertex_inputs=[("VEC2", "position")], varyings=[("VEC2", "uv")],
                           fragment_outputs=[("VEC4", "color")])


def _stages(fragment: str) -> dict:
    return {"vertex": "fullscreen_triangle.vert.glsl", "fragment": f"view/{fragment}.frag.glsl"}


def _resolve(*args, **kwargs):
    return resolve(*args, **kwargs)


#: The view stages' shaders (compiled once per process, freed with free_shaders()). Not a frame pass
#: of PASSES: they run after the frame's passes, on their textures, for the viewport only.
VIEW = GPUPass(
    name="view",
    label="View Resolve",
    step=Step("view_resolve", "View Resolve"),
    shaders={"resolve": ShaderSpec(_resolve_interface, _stages("resolve")),
             "jbu_weights": ShaderSpec(_weights_interface, _stages("jbu_weights")),
             "resolve_weighted": ShaderSpec(_resolve_weighted_interface, _stages("resolve_weighted")),
             "accumulate": ShaderSpec(_accumulate_interface, _stages("accumulate")),
             "display": ShaderSpec(_display_interface, _stages("display"))},
    reads=("gbuffer", "direct_light", "vsgl_shading"),
    writes=("view_accumulation",),
    run=_resolve,
)


def _black():
    """One black RGBA32F texel: a view render without a pass's image (its upsampling is black)."""
    def make():
        import gpu

        texture = gpu.types.GPUTexture((1, 1), format="RGBA32F")
        texture.clear(format="FLOAT", value=(0.0, 0.0, 0.0, 0.0))
        return texture

    return VIEW.resource("black", make)


def _batch():
    return VIEW.resource("fullscreen_triangle", lambda: fullscreen_triangle_batch(VIEW.shader("resolve")))


class ViewTarget:
    """The accumulation images of one view (IMAGES, RGBA32F, width × height) and their framebuffer."""

    IMAGES = IMAGES

    def __init__(self, width: int, height: int):
        import gpu

        self.size = (int(width), int(height))
        self.textures = {name: gpu.types.GPUTexture(self.size, format="RGBA32F") for name in self.IMAGES}
        self.framebuffer = gpu.types.GPUFrameBuffer(color_slots=[self.textures[name] for name in self.IMAGES])
        self.clear()

    def clear(self) -> None:
        with self.framebuffer.bind():
            self.framebuffer.clear(color=(0.0, 0.0, 0.0, 0.0))

    def finish(self) -> None:
        finish(self.textures[self.IMAGES[0]])

    def free(self) -> None:
        self.framebuffer = None
        self.textures.clear()

    def resource_count(self) -> int:
        return len(self.textures) + (self.framebuffer is not None)


def _draw_into(target: ViewTarget, rows, blend: str, shader: str, set_inputs) -> None:
    """Draw the full-screen triangle with VIEW's `shader` (inputs set by `set_inputs(program)`) into
    rows [first, end) of `target`, with `blend`; the GPU state is restored after. The shader and
    batch are made before the framebuffer is bound: compiling while it is bound leaves another one
    bound in Blender 5.2 (the bind's exit then fails)."""
    import gpu

    program = VIEW.shader(shader)
    batch = _batch()
    first, end = rows if rows is not None else (0, target.size[1])
    saved = (gpu.state.blend_get(), gpu.state.depth_test_get(), gpu.state.depth_mask_get(),
             tuple(gpu.state.viewport_get()))
    try:
        with target.framebuffer.bind():
            gpu.state.viewport_set(0, int(first), target.size[0], int(end - first))
            gpu.state.depth_test_set("NONE")
            gpu.state.depth_mask_set(False)
            gpu.state.blend_set(blend)
            program.bind()
            set_inputs(program)
            batch.draw(program)
    finally:
        gpu.state.blend_set(saved[0])
        gpu.state.depth_test_set(saved[1])
        gpu.state.depth_mask_set(saved[2])
        gpu.state.viewport_set(*saved[3])


def _bind_low_images(program, view, names) -> None:
    """`view`'s textures `names` as the images low_NAME (a pass that did not run: a black texel)."""
    for name in names:
        texture = view.textures.get(name)
        program.image(f"low_{name}", texture if texture is not None else _black())


def resolve(view, guide_position, guide_normal, camera, projection_11: float, target: ViewTarget,
            rows=None, weight: float = 1.0, add: bool = False) -> None:
    """`view` (renderer.ViewTextures) upsampled to the guide's pixels into rows [first, end) of
    `target` (the guide covers those rows), times `weight`; added to what is there if `add`."""
    def set_inputs(program):
        program.uniform_float("camera", tuple(float(v) for v in camera))
        program.uniform_float("projection_11", float(projection_11))
        program.uniform_float("sigma_position", SIGMA_POSITION)
        program.uniform_float("normal_power", NORMAL_POWER)
        program.uniform_float("weight", float(weight))
        _bind_low_images(program, view, LOW_IMAGES)
        program.uniform_sampler("guide_position", guide_position)
        program.uniform_sampler("guide_normal", guide_normal)

    _draw_into(target, rows, "ADDITIVE" if add else "NONE", "resolve", set_inputs)


def jbu_weights(low_position, low_normal, guide_position, guide_normal, camera, projection_11: float,
                target: "GuideWeights") -> None:
    """The upsampler's weights of every guide pixel for renders whose G-buffer is (low_position,
    low_normal) into `target` (the guide's size)."""
    def set_inputs(program):
        program.uniform_float("camera", tuple(float(v) for v in camera))
        program.uniform_float("projection_11", float(projection_11))
        program.uniform_float("sigma_position", SIGMA_POSITION)
        program.uniform_float("normal_power", NORMAL_POWER)
        program.image("low_position", low_position)
        program.image("low_normal", low_normal)
        program.uniform_sampler("guide_position", guide_position)
        program.uniform_sampler("guide_normal", guide_normal)

    _draw_into(target, None, "NONE", "jbu_weights", set_inputs)


def resolve_weighted(view, weights: "GuideWeights", target: ViewTarget, weight: float = 1.0,
                     add: bool = False) -> None:
    """resolve() of `view` with kept `weights` (jbu_weights of a render of its size, view and
    triangles), into the whole of `target` (the weights' size): the same floats."""
    def set_inputs(program):
        program.uniform_float("weight", float(weight))
        _bind_low_images(program, view, LOW_IMAGES[:6])
        for name in WEIGHT_IMAGES:
            program.image(name, weights.textures[name])

    _draw_into(target, None, "ADDITIVE" if add else "NONE", "resolve_weighted", set_inputs)


class GuideWeights(ViewTarget):
    """jbu_weights' images (WEIGHT_IMAGES, RGBA32F, the guide's size) for renders of `low_size`."""

    IMAGES = WEIGHT_IMAGES

    def __init__(self, width: int, height: int):
        super().__init__(width, height)
        self.low_size = None


def _warm_kept_weights() -> None:
    """Once per compile of the view shaders: jbu_weights and resolve_weighted drawn into one-texel
    targets, since llvmpipe compiles a shader's machine code at its first draw, not when Blender
    creates it; the first guide's coarse image compiles the rest of the view stages anyway."""
    def make():
        black = _black()
        one = SimpleNamespace(width=1, height=1, textures={"position": black, "normal": black})
        weights, target = GuideWeights(1, 1), ViewTarget(1, 1)
        try:
            jbu_weights(black, black, black, black, (0.0, 0.0, 0.0, 1.0), 1.0, weights)
            resolve_weighted(one, weights, target)
            target.finish()
        finally:
            weights.free()
            target.free()
        return None

    VIEW.resource("kept_weights_warm", make)


class WeightsPool:
    """GuideWeights kept across guides, by size: on llvmpipe a region-sized pair of RGBA32F textures
    took 20-140 ms to create, as much as the kept weights save in a coarse image. A guide takes one
    when it is made (its coarse image pays for the view change anyway) and gives it back when freed;
    free() releases the idle ones."""

    def __init__(self):
        self._idle: dict = {}  # size -> [GuideWeights]

    def take(self, size) -> GuideWeights:
        idle = self._idle.get(tuple(size))
        return idle.pop() if idle else GuideWeights(*size)

    def give(self, weights: GuideWeights) -> None:
        weights.low_size = None
        self._idle.setdefault(tuple(weights.size), []).append(weights)

    def free(self) -> None:
        for idle in self._idle.values():
            for weights in idle:
                weights.free()
        self._idle.clear()

    def __len__(self) -> int:
        return sum(len(idle) for idle in self._idle.values())


class ViewGuide:
    """A viewport's full-resolution guide (passes.gbuffer.GBuffer) and the upsampler's weights for
    the last render size it guided, kept and freed together.

    The weights depend on the guide and on the render's G-buffer alone. The view pipeline keeps a
    guide only while the view and the triangles stay (view_pipeline.ViewPipeline._full_guide), and a
    render of the same size then rasterises the same G-buffer; so after a light, material or setting
    change the coarse image is resolve_weighted alone (benchmarks/results/resolve_weights.md)."""

    def __init__(self, gbuffer, pool: WeightsPool | None = None):
        self.gbuffer = gbuffer
        self.pool = pool  # where the weights' textures come from and go back to (else made when needed)
        self.weights = pool.take(self.size) if pool is not None else None
        self.weight_builds = 0
        self.renders = 0  # renders this guide has resolved
        self._last_low_size = None  # the size of the last of them

    @property
    def textures(self):
        return self.gbuffer.textures

    @property
    def view_matrix(self):
        return self.gbuffer.view_matrix

    @property
    def projection_matrix(self):
        return self.gbuffer.projection_matrix

    @property
    def size(self):
        return (self.gbuffer.width, self.gbuffer.height)

    def weights_for(self, view, camera, projection_11: float) -> GuideWeights | None:
        """The weights for renders of `view`'s size: kept ones, or computed from its G-buffer when
        the guide's last render had the same size; else None (resolve in one pass). Computing them
        and resolving with them costs more than the one pass (the weights are written and read
        back), so they are made only where a size repeats: a guide that serves one render, as while
        the view moves, or a coarse size that changes from edit to edit, would pay for them each
        time (benchmarks/results/first_coarse_image_resolve_weights.md)."""
        low_size = (view.width, view.height)
        self.renders += 1
        repeated, self._last_low_size = self._last_low_size == low_size, low_size
        if self.weights is not None and self.weights.low_size == low_size:
            return self.weights
        if not repeated:
            return None
        if self.weights is None:
            self.weights = GuideWeights(*self.size)
        if self.weights.low_size != low_size:
            jbu_weights(view.textures["position"], view.textures["normal"], self.textures["position"],
                        self.textures["normal"], camera, projection_11, self.weights)
            self.weights.low_size = low_size
            self.weight_builds += 1
        return self.weights

    def free(self) -> None:
        if self.weights is not None:
            if self.pool is not None:
                self.pool.give(self.weights)
            else:
                self.weights.free()
        self.weights = None
        self.gbuffer.free()


def accumulate(source: ViewTarget, target: ViewTarget, weight: float = 1.0, add: bool = True) -> None:
    """`source` × weight added to (or, add=False, copied into) `target` (same size)."""
    def set_inputs(program):
        program.uniform_float("weight", float(weight))
        for name in IMAGES:
            program.image(f"source_{name}", source.textures[name])

    _draw_into(target, None, "ADDITIVE" if add else "NONE", "accumulate", set_inputs)


#: The display shader's `composition`: opaque (Rendered shading), over the viewport by coverage,
#: added onto it (the overlay's two ways).
OPAQUE, OVER, ADDED = 0, 1, 2


def display(target: ViewTarget, weight: float, view_pass: str, look=None) -> None:
    """Draw `target` × weight into the bound framebuffer as VIEWPORT_PASSES option `view_pass`:
    opaque and linear (Rendered shading: Blender's colour management follows), or, with `look`
    (view_pipeline.OverlayLook), as the overlay lays it over another engine's viewport."""
    import gpu

    mode = VIEWPORT_PASSES.number(view_pass) if view_pass in VIEWPORT_PASSES.names else 0
    composition = OPAQUE if look is None else (ADDED if look.added else OVER)
    program = VIEW.shader("display")
    batch = _batch()
    saved = gpu.state.blend_get()
    try:
        gpu.state.blend_set({OPAQUE: "NONE", OVER: "ALPHA", ADDED: "ADDITIVE_PREMULT"}[composition])
        program.bind()
        program.uniform_int("mode", mode)
        program.uniform_float("weight", float(weight))
        program.uniform_int("composition", composition)
        program.uniform_float("scale", float(look.scale) if look is not None else 1.0)
        program.uniform_float("gamma", float(look.gamma) if look is not None else 1.0)
        program.uniform_int("encode_srgb", int(bool(look.encode_srgb)) if look is not None else 0)
        for name in IMAGES:
            program.uniform_sampler(f"accum_{name}", target.textures[name])
        batch.draw(program)
    finally:
        gpu.state.blend_set(saved)


class GPUViewBackend:
    """What view_pipeline.ViewPipeline renders and draws with: the renderer's passes, the view stages
    above. Tests of the scheduling replace it with a fake one (no Blender, no GPU)."""

    def frame_renderer(self):
        from .renderer import FrameRenderer

        return FrameRenderer()

    def cost_model(self):
        """This GPU's cost model from the user's cache (budget.py; the built-in one without a cache)."""
        import gpu

        from .budget import load_model

        return load_model(gpu.platform.renderer_get())

    #: passes.scene_gpu.PointTextureCache of this backend's builds, made on first use.
    point_cache = None

    def scene_lights(self, description, settings):
        from .passes.scene_gpu import PointTextureCache
        from .renderer import SceneLights

        if self.point_cache is None:
            self.point_cache = PointTextureCache()
        return SceneLights.build(description, settings, point_cache=self.point_cache)

    def scene_lights_stages(self, description, settings):
        """scene_lights as a generator of its stages (renderer.SceneLights.build_stages), returning
        the same SceneLights."""
        from .passes.scene_gpu import PointTextureCache
        from .renderer import SceneLights

        if self.point_cache is None:
            self.point_cache = PointTextureCache()
        return SceneLights.build_stages(description, settings, point_cache=self.point_cache)

    def free(self) -> None:
        """Drop the point sets kept across builds and the guides' idle weights."""
        if self.point_cache is not None:
            self.point_cache.free()
        self.point_cache = None
        if self.weights_pool is not None:
            self.weights_pool.free()
        self.weights_pool = None

    def gpu_resource_count(self) -> int:
        return ((len(self.point_cache) if self.point_cache is not None else 0)
                + (len(self.weights_pool) if self.weights_pool is not None else 0))

    def render_view(self, renderer, lights, settings, width, height, view_matrix, projection_matrix,
                    preview: bool = False):
        """``preview``: the coarse image after a change, whose glossy VPL pass shades one VPL of each
        block of S, weighted S (reference.vpl_culling.preview_stride: 16 at 128 x 128; on the demo
        0.30 % relative RMSE at 82 x 49, 0.78 % at 328 x 197); the samples that refine it shade them
        all, so the converged image is the same."""
        from .reference.vpl_culling import preview_stride

        stride = preview_stride(settings.rsm_size * settings.rsm_size) if preview else 1
        return renderer.render_view_textures(lights, settings, width, height, view_matrix, projection_matrix,
                                             vpl_stride=stride)

    #: WeightsPool of this backend's guides, made on first use.
    weights_pool = None

    def guide(self, renderer, lights, width, height, view_matrix, projection_matrix) -> ViewGuide:
        # What a guide's kept weights need is made with the guide, whose coarse image pays for a
        # view change anyway, not at the first light edit that reuses it.
        _warm_kept_weights()
        if self.weights_pool is None:
            self.weights_pool = WeightsPool()
        return ViewGuide(renderer.guide(lights, width, height, view_matrix, projection_matrix), self.weights_pool)

    def target(self, width, height) -> ViewTarget:
        return ViewTarget(width, height)

    def resolve(self, view, guide, target, rows, weight=1.0, add=False) -> None:
        """`guide`: the GBuffer whose pixels are the rows' (the view's own for a full-resolution band),
        or a kept ViewGuide, whose weights serve every render of one size."""
        from .views import camera_vector

        camera = camera_vector(guide.view_matrix, guide.projection_matrix)
        projection_11 = float(np.asarray(guide.projection_matrix)[1, 1])
        if isinstance(guide, ViewGuide) and rows is None and (view.width, view.height) != guide.size:
            weights = guide.weights_for(view, camera, projection_11)
            if weights is not None:
                resolve_weighted(view, weights, target, weight, add)
                return
        resolve(view, guide.textures["position"], guide.textures["normal"], camera, projection_11, target, rows,
                weight, add)

    def finish_view(self, view) -> None:
        """Wait for a view render's passes (one texel read), so its time is theirs alone."""
        from .passes.gpu_util import finish

        finish(view.textures["indirect_diffuse"])

    def guide_of(self, view):
        """The G-buffer a full-resolution view render carries (its own guide)."""
        return view.gbuffer

    def accumulate(self, source, target, weight=1.0, add=True) -> None:
        accumulate(source, target, weight, add)

    def finish(self, target) -> None:
        target.finish()

    def display(self, target, weight, view_pass, look=None) -> None:
        display(target, weight, view_pass, look)


def free_shaders() -> None:
    VIEW.free_shaders()


# Like the passes' shaders: released while Blender's GPU backend is still alive (passes/__init__.py).
atexit.register(free_shaders)
