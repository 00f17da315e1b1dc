"""The MeshMatch panel in the 3D view's sidebar (N panel, MeshMatch tab)."""

import bpy
from bpy.props import EnumProperty, IntProperty, PointerProperty, StringProperty

from .operators import SWATCHES


class MeshMatchSettings(bpy.types.PropertyGroup):
    vertices: IntProperty(name="Working vertices", default=64000, min=128, max=4000000,
                          description="MeshMatch working resolution (transfer, complete)")
    seed: IntProperty(name="Seed", default=0, min=0)
    image: StringProperty(name="Exemplar", description="Image to synthesize from")
    swatch: EnumProperty(name="Swatch", items=SWATCHES, default='chain')
    swatch_object: PointerProperty(name="Swatch object", type=bpy.types.Object)


class VIEW3D_PT_meshmatch(bpy.types.Panel):
    bl_label = "MeshMatch"
    bl_space_type = 'VIEW_3D'
    bl_region_type = 'UI'
    bl_category = "MeshMatch"

    def draw(self, context):
        s = context.scene.meshmatch
        col = self.layout.column(align=True)
        col.prop(s, "vertices")
        col.prop(s, "seed")
        box = self.layout.box()
        box.label(text="Active = source, selected = targets")
        op = box.operator("meshmatch.transfer", icon='TEXTURE')
        op.vertices, op.seed = s.vertices, s.seed
        box.operator("meshmatch.add_pair", icon='EMPTY_AXIS')
        op = box.operator("meshmatch.weather", icon='BRUSH_DATA')
        op.seed = s.seed
        box = self.layout.box()
        box.label(text="Active mesh")
        op = box.operator("meshmatch.complete", icon='VPAINT_HLT')
        op.vertices, op.seed = s.vertices, s.seed
        op = box.operator("meshmatch.curves", icon='CURVE_DATA')
        op = box.operator("meshmatch.feature_maps", icon='IMAGE_RGB')
        op.seed = s.seed
        box = self.layout.box()
        box.prop_search(s, "image", bpy.data, "images")
        row = box.row(align=True)
        op = row.operator("meshmatch.synthesize", icon='IMAGE_DATA')
        op.image, op.seed = s.image, s.seed
        op = row.operator("meshmatch.synthesize", text="Along Features", icon='CURVE_DATA')
        op.image, op.seed = s.image, s.seed
        op.orientation, op.align_features = 'features', True
        box = self.layout.box()
        box.prop(s, "swatch")
        if s.swatch == 'OBJECT':
            box.prop(s, "swatch_object")
        op = box.operator("meshmatch.quilt", icon='MOD_ARRAY')
        op.swatch = s.swatch
        op.swatch_object = s.swatch_object.name if s.swatch_object else ""


classes = (MeshMatchSettings, VIEW3D_PT_meshmatch)
