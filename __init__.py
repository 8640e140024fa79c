# SPDX-License-Identifier: GPL-3.0-or-later
"""Entry module of the VSGL Indirect Light extension (see blender_manifest.toml).

Blender imports this folder as the package ``bl_ext.<repository>.vsgl``, so everything below it
is reached through relative imports only, and there is no ``bl_info`` (the manifest replaces it).
The add-on itself lives in ``vsgl_addon/``; this file only hands Blender its register/unregister.
"""

# pytest imports the repository's root as a package named after its folder, and a clone's folder
# name need not be a Python identifier: then this runs as a plain module, with no package to be
# relative to, and has nothing to hand over.
if __package__:
    from .vsgl_addon import register, unregister

    __all__ = ("register", "unregister")
