"""MeshMatch for Blender: example-based texturing in the 3D view's sidebar, built on the
`meshmatch` Python package (bundled as a wheel in the extension zip)."""

import bpy

from . import operators, panel

_classes = operators.classes + panel.classes


def register():
    for cls in _classes:
        bpy.utils.register_class(cls)
    bpy.types.Scene.meshmatch = bpy.props.PointerProperty(type=panel.MeshMatchSettings)


def unregister():
    del bpy.types.Scene.meshmatch
    for cls in reversed(_classes):
        bpy.utils.unregister_class(cls)
