# SPDX-License-Identifier: GPL-3.0-or-later
"""Joint bilateral upsampling: the float64 twin (vsgl_addon/reference/bilateral.py) against a
brute-force scalar loop and the properties the viewport relies on (identity at equal resolution,
partition of unity, edges kept, no NaN at the parameters' ends), and glsl/lib/bilateral.glsl
against the twin on llvmpipe."""

from __future__ import annotations

import math

import numpy as np
import pytest

from glsl_harness import as_gpu_floats, evaluate_glsl
from vsgl_addon.reference.bilateral import (JBU_MIN_WEIGHT, jbu_apply, jbu_footprint, jbu_range_weight, jbu_weights,
                                            joint_bilateral_upsample)


def _brute_force(low, low_position, low_normal, uv, position, normal, footprint, sigma, power):
    """Eq. 2 of Kopf et al. 2007 with the bilinear spatial kernel, one pixel and one texel at a time."""
    h, w = low.shape[:2]
    out = []
    for k in range(len(uv)):
        qx, qy = uv[k, 0] * w - 0.5, uv[k, 1] * h - 0.5
        bx, by = math.floor(qx), math.floor(qy)
        fx, fy = qx - bx, qy - by

        def weight(tx, ty, s):
            lp = low_position[ty, tx]
            if lp[3] <= 0:
                return 0.0
            d = (position[k] - lp[:3]) / max(footprint[k] * s, 1e-30)
            c = float(np.dot(normal[k], low_normal[ty, tx, :3]))
            return math.exp(-0.5 * min(float(np.dot(d, d)), 1e4)) * (c ** power if c > 0 else 0.0)

        total, wsum = np.zeros(low.shape[-1]), 0.0
        for oy in (0, 1):
            for ox in (0, 1):
                tx, ty = min(max(bx + ox, 0), w - 1), min(max(by + oy, 0), h - 1)
                ws = (1 - fx if ox == 0 else fx) * (1 - fy if oy == 0 else fy)
                wk = ws * weight(tx, ty, sigma)
                total += wk * low[ty, tx]
                wsum += wk
        if wsum > JBU_MIN_WEIGHT:
            out.append(total / wsum)
            continue
        best, pick = 0.0, np.zeros(low.shape[-1])
        for j in range(-1, 3):
            for i in range(-1, 3):
                tx, ty = min(max(bx + i, 0), w - 1), min(max(by + j, 0), h - 1)
                if low_position[ty, tx, 3] <= 0:
                    continue
                wt = weight(tx, ty, 4 * sigma) + 1e-6 / (1 + (tx - qx) ** 2 + (ty - qy) ** 2)
                if wt > best:
                    best, pick = wt, low[ty, tx]
        out.append(pick)
    return np.array(out)


def _scene(rng, h=5, w=7, background=0.2):
    """A random low-resolution image with its guides (two depth layers, some background)."""
    low = rng.uniform(0.0, 2.0, (h, w, 4))
    position = np.zeros((h, w, 4))
    position[..., :2] = np.stack(np.meshgrid(np.arange(w) + 0.5, np.arange(h) + 0.5), -1) * 0.1
    position[..., 2] = np.where(rng.random((h, w)) < 0.5, 0.0, 0.3)
    position[..., 3] = (rng.random((h, w)) > background).astype(float)
    normal = np.zeros((h, w, 4))
    normal[..., :3] = rng.normal(size=(h, w, 3)) * 0.3 + [0, 0, 1]
    normal[..., :3] /= np.linalg.norm(normal[..., :3], axis=-1, keepdims=True)
    return low, position, normal


def _pixels(rng, low_position, low_normal, n):
    h, w = low_position.shape[:2]
    uv = rng.uniform(0.0, 1.0, (n, 2))
    texel = np.minimum((uv * [w, h]).astype(int), [w - 1, h - 1])
    position = low_position[texel[:, 1], texel[:, 0], :3] + rng.normal(size=(n, 3)) * 0.02
    normal = low_normal[texel[:, 1], texel[:, 0], :3]
    return uv, position, normal, np.full(n, 0.1)


def test_reference_matches_brute_force():
    rng = np.random.default_rng(3)
    low, low_position, low_normal = _scene(rng)
    uv, position, normal, footprint = _pixels(rng, low_position, low_normal, 300)
    for sigma, power in ((1.0, 8.0), (0.3, 1.0), (4.0, 64.0)):
        got = joint_bilateral_upsample(low, low_position, low_normal, uv, position, normal, footprint, sigma, power)
        expected = _brute_force(low, low_position, low_normal, uv, position, normal, footprint, sigma, power)
        np.testing.assert_allclose(got, expected, rtol=1e-12, atol=1e-12)


def test_identity_at_equal_resolution_and_partition_of_unity():
    rng = np.random.default_rng(4)
    low, low_position, low_normal = _scene(rng, background=0.0)
    h, w = low.shape[:2]
    ys, xs = np.mgrid[0:h, 0:w]
    uv = np.stack([(xs + 0.5) / w, (ys + 0.5) / h], -1).reshape(-1, 2)
    got = joint_bilateral_upsample(low, low_position, low_normal, uv, low_position[..., :3].reshape(-1, 3),
                                   low_normal[..., :3].reshape(-1, 3), np.full(h * w, 0.1))
    np.testing.assert_allclose(got, low.reshape(-1, 4), rtol=1e-12)
    # A constant image stays constant wherever the guide finds geometry.
    uv, position, normal, footprint = _pixels(rng, low_position, low_normal, 200)
    constant = np.full_like(low, 0.75)
    got = joint_bilateral_upsample(constant, low_position, low_normal, uv, position, normal, footprint)
    np.testing.assert_allclose(got, 0.75, rtol=1e-12)


def test_a_depth_edge_stays_sharp_where_bilinear_blends():
    """Two surfaces meet between texel columns 1 and 2 of a 4-texel-wide image: full-resolution
    pixels on each side take only their own surface's value; bilinear mixes both."""
    low = np.zeros((1, 4, 4))
    low[0, :2], low[0, 2:] = 1.0, 5.0
    low_position = np.zeros((1, 4, 4))
    low_position[0, :, 0] = [0.05, 0.15, 0.25, 0.35]
    low_position[0, :2, 2], low_position[0, 2:, 2] = 0.0, 3.0  # far apart in depth
    low_position[..., 3] = 1.0
    low_normal = np.zeros((1, 4, 4))
    low_normal[..., 2] = 1.0
    u = (np.arange(16) + 0.5) / 16  # a 4x upsampling
    uv = np.stack([u, np.full(16, 0.5)], -1)
    position = np.stack([u * 0.4, np.zeros(16), np.where(u < 0.5, 0.0, 3.0)], -1)
    got = joint_bilateral_upsample(low, low_position, low_normal, uv, position,
                                   np.tile([0.0, 0.0, 1.0], (16, 1)), np.full(16, 0.1))[:, 0]
    np.testing.assert_allclose(got, np.where(u < 0.5, 1.0, 5.0), rtol=1e-9)
    q = np.clip(u * 4 - 0.5, 0, 3)
    bilinear = np.interp(q, np.arange(4), low[0, :, 0])
    assert np.abs(bilinear - np.where(u < 0.5, 1.0, 5.0)).max() > 1.0


def test_extremes_are_finite_and_background_gives_zero():
    rng = np.random.default_rng(5)
    low, low_position, low_normal = _scene(rng)
    uv, position, normal, _ = _pixels(rng, low_position, low_normal, 100)
    for footprint in (1e-30, 1e-6, 1.0, 1e6, 1e30):
        for sigma, power in ((1e-6, 1e-3), (1.0, 8.0), (1e6, 1e3)):
            got = joint_bilateral_upsample(low, low_position, low_normal, uv, position, normal,
                                           np.full(100, footprint), sigma, power)
            assert np.isfinite(got).all()
    empty = low_position.copy()
    empty[..., 3] = 0.0
    got = joint_bilateral_upsample(low, empty, low_normal, uv, position, normal, np.full(100, 0.1))
    assert (got == 0).all()
    one = joint_bilateral_upsample(low[:1, :1], low_position[:1, :1] * [1, 1, 1, 0] + [0, 0, 0, 1],
                                   low_normal[:1, :1], uv, position, normal, np.full(100, 1e6))
    np.testing.assert_allclose(one, np.broadcast_to(low[0, 0], one.shape))


def test_footprint_perspective_and_orthographic():
    positions = np.array([[0.0, 0.0, -2.0], [0.0, 0.0, -8.0]])
    perspective = jbu_footprint([0, 0, 0, 1], positions, 2.0, 100)
    np.testing.assert_allclose(perspective, [2.0 * 2 / 200, 8.0 * 2 / 200])
    np.testing.assert_allclose(jbu_footprint([0, 0, 1, 0], positions, 0.5, 10), [0.4, 0.4])
    assert jbu_range_weight([0, 0, 0], [0, 0, 1], [0, 0, 0, 0], [0, 0, 1], 1.0, 1.0, 8.0) == 0.0


@pytest.mark.gpu
def test_glsl_matches_reference():
    rng = np.random.default_rng(6)
    low, low_position, low_normal = (as_gpu_floats(a.reshape(-1, 4)).reshape(a.shape) for a in _scene(rng))
    n = 4000
    uv, position, normal, footprint = _pixels(rng, low_position, low_normal, n)
    footprint = rng.choice([1e-3, 0.05, 0.1, 1.0, 1e3], n)
    uv, position, normal, footprint = (as_gpu_floats(a) for a in (uv, position, normal, footprint))
    out = evaluate_glsl("joint_bilateral_upsample(low_image, low_position_image, low_normal_image, uv, "
                        "position, normal, footprint, 1.0, 8.0)",
                        {"uv": uv, "position": position, "normal": normal, "footprint": footprint}, 4,
                        libraries=["lib/bilateral.glsl"],
                        images={"low_image": low, "low_position_image": low_position, "low_normal_image": low_normal})
    expected = joint_bilateral_upsample(low, low_position, low_normal, uv, position, normal, footprint)
    assert np.isfinite(out).all()
    close = np.all(np.abs(out - expected) <= 1e-4 * np.abs(expected) + 1e-5, axis=-1)
    # Only pixels whose four weights sum to within float32 rounding of the fallback threshold, or
    # whose best fallback texels tie, may pick another branch on the GPU.
    assert close.mean() > 0.999, (close.mean(), np.argwhere(~close)[:5].ravel())


# The upsampler as the viewport's resolve ran it before the weights were shared: the whole filter
# per image (glsl/lib/bilateral.glsl's loop, each image's own texture size).
_PER_IMAGE = """
vec4 jbu_per_image(sampler2D low, sampler2D low_position, sampler2D low_normal, vec2 uv, vec3 position,
                   vec3 normal, float footprint, float sigma_position, float normal_power)
{
  ivec2 size = textureSize(low, 0);
  vec2 q = uv * vec2(size) - 0.5;
  vec2 base_f = floor(q);
  vec2 f = q - base_f;
  ivec2 base = ivec2(base_f);
  ivec2 hi = size - 1;
  vec4 sum = vec4(0.0);
  float weight_sum = 0.0;
  for (int k = 0; k < 4; k++) {
    ivec2 o = ivec2(k & 1, k >> 1);
    ivec2 t = clamp(base + o, ivec2(0), hi);
    float ws = (o.x == 0 ? 1.0 - f.x : f.x) * (o.y == 0 ? 1.0 - f.y : f.y);
    float w = ws * jbu_range_weight(position, normal, texelFetch(low_position, t, 0),
                                    texelFetch(low_normal, t, 0), footprint, sigma_position, normal_power);
    sum += w * texelFetch(low, t, 0);
    weight_sum += w;
  }
  if (weight_sum > JBU_MIN_WEIGHT) {
    return sum / weight_sum;
  }
  float best = 0.0;
  vec4 pick = vec4(0.0);
  for (int j = -1; j <= 2; j++) {
    for (int i = -1; i <= 2; i++) {
      ivec2 t = clamp(base + ivec2(i, j), ivec2(0), hi);
      vec4 p = texelFetch(low_position, t, 0);
      if (p.a <= 0.0) {
        continue;
      }
      vec2 dt = vec2(t) - q;
      float w = jbu_range_weight(position, normal, p, texelFetch(low_normal, t, 0), footprint,
                                 4.0 * sigma_position, normal_power) + 1e-6 / (1.0 + dot(dt, dt));
      if (w > best) {
        best = w;
        pick = texelFetch(low, t, 0);
      }
    }
  }
  return pick;
}
"""


@pytest.mark.gpu
def test_shared_weights_give_the_per_image_filter_bit_for_bit():
    """The resolve's six images with one jbu_weights per pixel (glsl/view/resolve.frag.glsl) against
    the whole filter run per image: identical float32 results, a pass's 1x1 black texel included
    (the viewport's image does not change, only its cost), over the four-texel, fallback and
    background branches. The twin's jbu_apply of shared weights is the per-image twin too."""
    rng = np.random.default_rng(7)
    _, low_position, low_normal = _scene(rng, h=9, w=11, background=0.3)
    low_position[:5, :5, 3] = 0.0  # a corner of background: no geometry among a pixel's sixteen
    low_position, low_normal = (as_gpu_floats(a.reshape(-1, 4)).reshape(a.shape) for a in (low_position, low_normal))
    images = {f"low_{k}": as_gpu_floats(rng.uniform(0.0, 3.0, low_position.shape).reshape(-1, 4)).reshape(low_position.shape)
              for k in range(5)}
    images["low_5"] = np.zeros((1, 1, 4))
    n = 6000
    uv, position, normal, footprint = _pixels(rng, low_position, low_normal, n)
    footprint = rng.choice([1e-3, 0.05, 0.1, 1.0, 1e3], n)
    uv, position, normal, footprint = (as_gpu_floats(a) for a in (uv, position, normal, footprint))
    inputs = {"uv": uv, "position": position, "normal": normal, "footprint": footprint}
    args = "low_position_image, low_normal_image, uv, position, normal, footprint, 1.0, 8.0"
    shared = "JBUWeights jw = jbu_weights(" + args + ");\n" + "".join(
        f"out{k} = jbu_apply(jw, low_{k});\n" for k in range(6))
    per_image = "".join(f"out{k} = jbu_per_image(low_{k}, {args});\n" for k in range(6))
    outputs = {f"out{k}": 4 for k in range(6)}
    textures = dict(images, low_position_image=low_position, low_normal_image=low_normal)
    got = evaluate_glsl(shared, inputs, outputs, libraries=["lib/bilateral.glsl"], images=textures)
    before = evaluate_glsl(per_image, inputs, outputs, libraries=["lib/bilateral.glsl"], declarations=_PER_IMAGE,
                           images=textures)
    kinds = jbu_weights(low_position, low_normal, uv, position, normal, footprint).kind
    assert {0, 1, 2} <= set(kinds.tolist())
    for k in range(6):
        assert np.array_equal(got[f"out{k}"], before[f"out{k}"]), k
    assert (got["out5"] == 0).all()
    jw = jbu_weights(low_position, low_normal, uv, position, normal, footprint)
    for k in range(5):
        np.testing.assert_array_equal(jbu_apply(jw, images[f"low_{k}"]),
                                      joint_bilateral_upsample(images[f"low_{k}"], low_position, low_normal, uv,
                                                               position, normal, footprint))


def _viewport_inputs(seed=8, low_h=9, low_w=11, scale=4):
    """A render of low_w x low_h texels (its images and G-buffer, float32-exact) and a guide
    `scale` times its size whose pixels sit near the render's surfaces, some uncovered."""
    rng = np.random.default_rng(seed)
    low, low_position, low_normal = _scene(rng, h=low_h, w=low_w, background=0.3)
    low_position[:3, :3, 3] = 0.0  # background all around some pixels
    low, low_position, low_normal = (as_gpu_floats(a.reshape(-1, 4)).reshape(a.shape)
                                     for a in (low, low_position, low_normal))
    h, w = low_h * scale, low_w * scale
    ys, xs = np.mgrid[0:h, 0:w]
    uv = np.stack([(xs + 0.5) / w, (ys + 0.5) / h], -1).reshape(-1, 2)
    texel = np.minimum((uv * [low_w, low_h]).astype(int), [low_w - 1, low_h - 1])
    guide_position = np.zeros((h * w, 4))
    guide_position[:, :3] = low_position[texel[:, 1], texel[:, 0], :3] + rng.normal(size=(h * w, 3)) * 0.02
    guide_position[:, 3] = 1.0
    guide_position[rng.random(h * w) < 0.05, 3] = 0.0
    guide_normal = np.zeros((h * w, 4))
    guide_normal[:, :3] = low_normal[texel[:, 1], texel[:, 0], :3]
    guide_position, guide_normal = (as_gpu_floats(a) for a in (guide_position, guide_normal))
    images = {"direct_diffuse": low, "indirect_diffuse": 0.5 * low, "indirect_specular": low[..., ::-1].copy(),
              "position": low_position, "normal": low_normal}
    return images, uv, guide_position, guide_normal, (w, h)


def _view(images, size):
    from types import SimpleNamespace

    from vsgl_addon.passes.gpu_util import texture_from_array

    return SimpleNamespace(width=size[0], height=size[1],
                           textures={name: texture_from_array(a.astype(np.float32)) for name, a in images.items()})


@pytest.mark.gpu
def test_viewport_resolve_reads_images_and_matches_the_reference():
    """The viewport's resolve (view_gpu.resolve: jbu_weights / jbu_apply's image overloads, the
    render's eight textures bound as images, the guides as samplers) against the twin at every
    pixel of a guide 4x the render's size, a pass's 1x1 black texel included: the four-texel,
    fallback and background branches."""
    from vsgl_addon import view_gpu
    from vsgl_addon.passes.gpu_util import read_texture, texture_from_array

    images, uv, guide_position, guide_normal, (w, h) = _viewport_inputs()
    low_position, low_normal = images["position"], images["normal"]
    low_h = low_position.shape[0]
    view = _view(images, (low_position.shape[1], low_h))
    camera, projection_11 = np.array([0.3, 0.4, 5.0, 1.0]), 1.5
    target = view_gpu.ViewTarget(w, h)
    try:
        view_gpu.resolve(view, *(texture_from_array(a.reshape(h, w, 4).astype(np.float32))
                                 for a in (guide_position, guide_normal)),
                         camera, projection_11, target)
        out = {name: read_texture(target.textures[name], w, h).reshape(-1, 4) for name in view_gpu.IMAGES}
    finally:
        target.free()
    covered = guide_position[:, 3] > 0
    footprint = jbu_footprint(camera, guide_position[:, :3], projection_11, low_h)
    jw = jbu_weights(low_position, low_normal, uv, guide_position[:, :3], guide_normal[:, :3], footprint)
    assert {0, 1, 2} <= set(jw.kind[covered].tolist())
    for name, source in (("direct", "direct_diffuse"), ("indirect_diffuse", "indirect_diffuse"),
                         ("indirect_specular", "indirect_specular")):
        expected = np.where(covered[:, None], jbu_apply(jw, images[source])[:, :3], 0.0)
        close = np.all(np.abs(out[name][:, :3] - expected) <= 1e-4 * np.abs(expected) + 1e-5, axis=-1)
        # Pixels within float32 rounding of the fallback threshold, or of a tie, may branch otherwise.
        assert close.mean() > 0.999, (name, close.mean())
        np.testing.assert_array_equal(out[name][:, 3], covered.astype(float))
    for name in ("indirect_caustics", "indirect_glossy_reflectors"):
        assert (out[name][:, :3] == 0).all()


@pytest.mark.gpu
def test_kept_weights_resolve_the_same_floats_for_every_render_of_their_size():
    """A kept guide (view_gpu.ViewGuide: jbu_weights.frag.glsl at the second render of a size in a
    row, then resolve_weighted) gives bit for bit what the one-pass resolve gives, for later renders of the
    same size and G-buffer with other images (the weights are not recomputed), over the four-texel,
    fallback and background branches; a render of another size gets its own weights."""
    from types import SimpleNamespace

    from vsgl_addon import view_gpu
    from vsgl_addon.passes.gpu_util import read_texture, texture_from_array

    images, uv, guide_position, guide_normal, (w, h) = _viewport_inputs()
    low_size = images["position"].shape[1::-1]
    # An eye at the origin (views.camera_vector of the identity view): the one-pass resolve below
    # gets the same camera.
    camera = np.array([0.0, 0.0, 0.0, 1.0])
    projection = np.diag([1.2, 1.5, -1.0, 0.0])
    gbuffer = SimpleNamespace(width=w, height=h, view_matrix=np.eye(4), projection_matrix=projection,
                              textures={name: texture_from_array(a.reshape(h, w, 4).astype(np.float32))
                                        for name, a in (("position", guide_position), ("normal", guide_normal))},
                              free=lambda: None)
    guide = view_gpu.ViewGuide(gbuffer)
    backend = view_gpu.GPUViewBackend()
    other = dict(images, direct_diffuse=images["indirect_specular"] * 3.0, indirect_specular=images["direct_diffuse"],
                 indirect_caustics=0.25 * images["direct_diffuse"])
    # A render of half the size: another G-buffer, so other weights.
    half = {name: a[::2, ::2].copy() for name, a in images.items()}
    targets = [view_gpu.ViewTarget(w, h) for _ in range(2)]
    try:
        # A render of another size than the last one's is resolved in one pass; the second of a size
        # in a row computes the weights, kept while renders of that size follow.
        for images_k, builds in ((images, 0), (other, 1), (images, 1), (half, 1), (half, 2), (images, 2),
                                 (other, 3), (images, 3)):
            view = _view(images_k, images_k["position"].shape[1::-1])
            backend.resolve(view, guide, targets[0], None)
            assert guide.weight_builds == builds
            view_gpu.resolve(view, guide.textures["position"], guide.textures["normal"], camera, 1.5, targets[1])
            got, expected = ({name: read_texture(t.textures[name], w, h) for name in view_gpu.IMAGES} for t in targets)
            for name in view_gpu.IMAGES:
                np.testing.assert_array_equal(got[name], expected[name], err_msg=name)
            assert (got["indirect_caustics"][..., :3] != 0).any() == ("indirect_caustics" in images_k)
        kinds = jbu_weights(images["position"], images["normal"], uv, guide_position[:, :3], guide_normal[:, :3],
                            jbu_footprint(camera, guide_position[:, :3], 1.5, low_size[1])).kind
        assert {0, 1, 2} <= set(kinds[guide_position[:, 3] > 0].tolist())
    finally:
        for target in targets:
            target.free()
        guide.free()
    assert guide.weights is None
