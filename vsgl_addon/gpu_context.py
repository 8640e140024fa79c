"""A GPU context for Blender's `gpu` module in background mode (`blender -b`, the bpy module).

Blender 5.2 has `gpu.init()`. Blender 5.0 has not: its `gpu` module only works once a render
engine with `bl_use_gpu_context = True` has rendered once in the process, after which it stays
usable on the main thread (shared/reference/blender-gpu.md). With a window the context already
exists and nothing is done.

When no OpenGL driver can be reached, Blender does not raise: libepoxy aborts the whole process.
So before asking Blender for a context we create (and destroy) a throw-away OpenGL 4.3 core
context through EGL with ctypes, which fails gracefully and lets us name what is missing.
"""

from __future__ import annotations

import ctypes
import ctypes.util

# Blender's GPU backend needs OpenGL 4.3 core (compute shaders, image load/store).
REQUIRED_GL_VERSION = (4, 3)

_EGL_DEFAULT_DISPLAY = 0
_EGL_NO_CONTEXT = None
_EGL_NO_CONFIG = None
_EGL_PLATFORM_SURFACELESS_MESA = 0x31DD
_EGL_OPENGL_API = 0x30A2
_EGL_NONE = 0x3038
_EGL_CONTEXT_MAJOR_VERSION = 0x3098
_EGL_CONTEXT_MINOR_VERSION = 0x30FB
_EGL_CONTEXT_OPENGL_PROFILE_MASK = 0x30FD
_EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT = 0x1

_MISSING_HELP = (
    "Blender's gpu module needs OpenGL {major}.{minor} (core profile) through EGL in background "
    "mode. On Debian/Ubuntu without a GPU, install Mesa's software renderer: "
    "`apt-get install libegl1 libegl-mesa0 libgl1-mesa-dri` (llvmpipe is enough)."
)


class GPUContextError(RuntimeError):
    """No GPU context can be had; the message names what is missing and how to get it."""


def _help() -> str:
    return _MISSING_HELP.format(major=REQUIRED_GL_VERSION[0], minor=REQUIRED_GL_VERSION[1])


def probe_opengl() -> str | None:
    """Try to create an OpenGL core context through EGL; return None when it works, else what failed.

    Never touches Blender's own context: only a private context is created and destroyed, and the
    display is not terminated (EGL displays are per process and Blender may share it).
    """
    name = ctypes.util.find_library("EGL") or "libEGL.so.1"
    try:
        egl = ctypes.CDLL(name)
    except OSError as error:
        return f"libEGL could not be loaded ({error})"
    egl.eglGetDisplay.restype = ctypes.c_void_p
    egl.eglGetDisplay.argtypes = [ctypes.c_void_p]
    egl.eglInitialize.argtypes = [ctypes.c_void_p, ctypes.POINTER(ctypes.c_int), ctypes.POINTER(ctypes.c_int)]
    egl.eglBindAPI.argtypes = [ctypes.c_uint]
    egl.eglCreateContext.restype = ctypes.c_void_p
    egl.eglCreateContext.argtypes = [ctypes.c_void_p, ctypes.c_void_p, ctypes.c_void_p, ctypes.POINTER(ctypes.c_int)]
    egl.eglDestroyContext.argtypes = [ctypes.c_void_p, ctypes.c_void_p]
    egl.eglGetError.restype = ctypes.c_int

    display = None
    if hasattr(egl, "eglGetPlatformDisplay"):
        # Headless Blender uses Mesa's surfaceless platform; the default display needs X11.
        egl.eglGetPlatformDisplay.restype = ctypes.c_void_p
        egl.eglGetPlatformDisplay.argtypes = [ctypes.c_uint, ctypes.c_void_p, ctypes.c_void_p]
        display = egl.eglGetPlatformDisplay(_EGL_PLATFORM_SURFACELESS_MESA, None, None)
    if not display:
        display = egl.eglGetDisplay(ctypes.c_void_p(_EGL_DEFAULT_DISPLAY))
    if not display:
        return f"EGL has no display (eglGetDisplay failed, EGL error 0x{egl.eglGetError():04X})"
    major, minor = ctypes.c_int(0), ctypes.c_int(0)
    if not egl.eglInitialize(display, ctypes.byref(major), ctypes.byref(minor)):
        return (f"EGL could not be initialised (EGL error 0x{egl.eglGetError():04X}): "
                "no EGL vendor library or Mesa driver was found")
    if not egl.eglBindAPI(_EGL_OPENGL_API):
        return f"EGL {major.value}.{minor.value} offers no desktop OpenGL API (eglBindAPI failed)"
    attributes = (ctypes.c_int * 7)(
        _EGL_CONTEXT_MAJOR_VERSION, REQUIRED_GL_VERSION[0],
        _EGL_CONTEXT_MINOR_VERSION, REQUIRED_GL_VERSION[1],
        _EGL_CONTEXT_OPENGL_PROFILE_MASK, _EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT,
        _EGL_NONE,
    )
    context = egl.eglCreateContext(display, _EGL_NO_CONFIG, _EGL_NO_CONTEXT, attributes)
    if not context:
        return (f"EGL could not create an OpenGL {REQUIRED_GL_VERSION[0]}.{REQUIRED_GL_VERSION[1]} "
                f"core context (EGL error 0x{egl.eglGetError():04X})")
    egl.eglDestroyContext(display, context)
    return None


def _gpu_works(gpu) -> bool:
    try:
        gpu.platform.backend_type_get()
    except SystemError:
        return False
    return True


def _create_context_by_rendering(bpy) -> None:
    """Blender 5.0: render a 1x1 image once with a GPU-context engine in a scene of our own.

    The user's data is left as it was: the scene and its camera are removed afterwards, and the
    "Render Result" image is removed if the render created it.
    """
    ran = []

    class _VSGLContextEngine(bpy.types.RenderEngine):
        bl_idname = "VSGL_GPU_CONTEXT"
        bl_label = "VSGL GPU context"
        bl_use_gpu_context = True

        def render(self, depsgraph):
            ran.append(True)

    had_render_result = "Render Result" in bpy.data.images
    bpy.utils.register_class(_VSGLContextEngine)
    scene = bpy.data.scenes.new("VSGL GPU context")
    camera_data = bpy.data.cameras.new("VSGL GPU context")
    camera = bpy.data.objects.new("VSGL GPU context", camera_data)
    try:
        scene.collection.objects.link(camera)
        scene.camera = camera
        scene.render.engine = _VSGLContextEngine.bl_idname
        scene.render.resolution_x = scene.render.resolution_y = 1
        scene.render.resolution_percentage = 100
        bpy.ops.render.render(scene=scene.name)
    finally:
        bpy.data.scenes.remove(scene)
        bpy.data.objects.remove(camera)
        bpy.data.cameras.remove(camera_data)
        bpy.utils.unregister_class(_VSGLContextEngine)
        if not had_render_result and "Render Result" in bpy.data.images:
            bpy.data.images.remove(bpy.data.images["Render Result"])
    if not ran:
        raise GPUContextError("Blender did not run the GPU-context render engine; " + _help())


def ensure_gpu_context() -> str:
    """Make the `gpu` module usable and return the renderer's name (e.g. "llvmpipe (LLVM 15 ...)").

    No-op when a context already exists (a window, or an earlier call). Raises GPUContextError
    with an actionable message when OpenGL cannot be had. Main thread only (Blender's rule).
    """
    import bpy
    import gpu

    if not bpy.app.background or _gpu_works(gpu):
        return gpu.platform.renderer_get()
    problem = probe_opengl()
    if problem is not None:
        raise GPUContextError(f"No GPU context in background mode: {problem}. {_help()}")
    if hasattr(gpu, "init"):
        gpu.init()
    else:
        _create_context_by_rendering(bpy)
    if not _gpu_works(gpu):
        raise GPUContextError("Blender's gpu module is still unavailable after initialisation. " + _help())
    return gpu.platform.renderer_get()
