"""Blender data to meshmatch and back: evaluated meshes in world space as `meshmatch.Mesh`,
results as colour attributes or image textures wired into the material."""

import bpy
import numpy as np

import meshmatch


class Extracted:
    """An object's evaluated mesh as meshmatch sees it, and how to map results back.

    `mesh` holds only the vertices some triangle uses; `vmap[i]` is the Blender vertex of its
    vertex i. `loops` is the Blender loop of every triangle corner (3 per triangle), for UVs.
    """

    def __init__(self, obj, mesh, vmap, loops, n_vertices, uv_name, world):
        self.obj = obj
        self.mesh = mesh
        self.vmap = vmap
        self.loops = loops
        self.n_vertices = n_vertices
        self.uv_name = uv_name
        self.world = world


def _srgb(linear):
    """Linear to sRGB transfer, for float images."""
    linear = np.clip(linear, 0.0, 1.0)
    return np.where(
        linear <= 0.0031308, linear * 12.92, 1.055 * np.power(linear, 1.0 / 2.4) - 0.055
    )


def image_to_array(image, keep_alpha=False):
    """A Blender image as (H, W, 3) uint8 sRGB, row 0 at the top ((H, W, 4) with alpha when
    `keep_alpha` and the image has an alpha channel, as the image's file is read by the CLI)."""
    w, h = image.size
    if w == 0 or h == 0:
        raise meshmatch.MeshMatchError(f"image {image.name}: has no pixels (is its file missing?)")
    buf = np.empty(w * h * 4, np.float32)
    image.pixels.foreach_get(buf)
    px = buf.reshape(h, w, 4)[::-1]
    rgb = px[:, :, :3]
    if image.is_float:
        rgb = _srgb(rgb)
    out = np.rint(np.clip(rgb, 0.0, 1.0) * 255.0).astype(np.uint8)
    if keep_alpha and image.depth in (32, 64, 128):  # the file has an alpha channel
        alpha = np.rint(np.clip(px[:, :, 3], 0.0, 1.0) * 255.0).astype(np.uint8)
        out = np.concatenate([out, alpha[:, :, None]], axis=2)
    return np.ascontiguousarray(out)


def _uses_nodes(mat):
    """Whether the material's node tree draws it (always from Blender 5.0, where `use_nodes`
    is deprecated)."""
    return bpy.app.version >= (5, 0, 0) or mat.use_nodes


def base_color_image(obj):
    """The image of the Image Texture node linked to a Principled BSDF's Base Color in the
    object's first material that has one, or None."""
    for slot in obj.material_slots:
        mat = slot.material
        if mat is None or mat.node_tree is None or not _uses_nodes(mat):
            continue
        for node in mat.node_tree.nodes:
            if node.type != 'BSDF_PRINCIPLED':
                continue
            base = node.inputs.get("Base Color")
            if base is None:
                continue
            for link in base.links:
                src = link.from_node
                if src.type == 'TEX_IMAGE' and src.image is not None:
                    return src.image
    return None


def extract(obj, depsgraph, colors=True, texture=True):
    """The object's evaluated mesh (modifiers applied), in world space, triangulated."""
    ev = obj.evaluated_get(depsgraph)
    me = ev.to_mesh()
    try:
        me.calc_loop_triangles()
        n = len(me.vertices)
        co = np.empty(n * 3, np.float32)
        me.vertices.foreach_get("co", co)
        co = co.reshape(n, 3).astype(np.float64)
        world = np.array(obj.matrix_world, dtype=np.float64)
        co = co @ world[:3, :3].T + world[:3, 3]
        nt = len(me.loop_triangles)
        if nt == 0:
            raise meshmatch.MeshMatchError(f"{obj.name}: the mesh has no faces")
        tri = np.empty(nt * 3, np.int32)
        me.loop_triangles.foreach_get("vertices", tri)
        loops = np.empty(nt * 3, np.int32)
        me.loop_triangles.foreach_get("loops", loops)
        used = np.unique(tri)
        remap = np.full(n, -1, np.int64)
        remap[used] = np.arange(len(used))
        faces = remap[tri].reshape(nt, 3)
        uvs = None
        uv_name = None
        if me.uv_layers.active is not None:
            layer = me.uv_layers.active
            uv_name = layer.name
            luv = np.empty(len(me.loops) * 2, np.float32)
            layer.uv.foreach_get("vector", luv)
            uvs = luv.reshape(-1, 2)[loops]
        cols = None
        attr = me.color_attributes.active_color if colors else None
        if attr is not None:
            buf = np.empty(len(attr.data) * 4, np.float32)
            attr.data.foreach_get("color_srgb", buf)
            rgba = buf.reshape(-1, 4)
            if attr.domain == 'POINT':
                per_vertex = rgba[:, :3]
            else:
                lv = np.empty(len(me.loops), np.int32)
                me.loops.foreach_get("vertex_index", lv)
                acc = np.zeros((n, 3))
                cnt = np.zeros(n)
                np.add.at(acc, lv, rgba[:, :3])
                np.add.at(cnt, lv, 1.0)
                per_vertex = acc / np.maximum(cnt, 1.0)[:, None]
            cols = np.clip(per_vertex[used], 0.0, 1.0).astype(np.float32)
        tex = None
        if texture and uvs is not None:
            image = base_color_image(obj)
            if image is not None:
                tex = image_to_array(image)
        mesh = meshmatch.Mesh(
            co[used].astype(np.float32),
            faces,
            colors=cols,
            uvs=uvs,
            texture=tex,
        )
        return Extracted(obj, mesh, used, loops, n, uv_name, world)
    finally:
        ev.to_mesh_clear()


def nearest_vertex(ex, point):
    """The meshmatch vertex of `ex` nearest a world-space point."""
    d = np.linalg.norm(ex.mesh.vertices - np.asarray(point, np.float32), axis=1)
    return int(np.argmin(d))


def _result_target(ex):
    """The mesh datablock to write a result on: the object's own when the evaluated mesh has its
    vertices (no modifier changed the topology), else a new object with the evaluated mesh."""
    obj = ex.obj
    if obj.data is not None and len(obj.data.vertices) == ex.n_vertices:
        return obj
    depsgraph = bpy.context.evaluated_depsgraph_get()
    me = bpy.data.meshes.new_from_object(obj.evaluated_get(depsgraph))
    new = bpy.data.objects.new(f"{obj.name} (MeshMatch)", me)
    new.matrix_world = obj.matrix_world.copy()
    for coll in obj.users_collection:
        coll.objects.link(new)
    return new


def write_colors(obj_or_ex, colors, name="MeshMatch"):
    """Per-vertex sRGB colours (meshmatch's vertices) as a point colour attribute, made active."""
    ex = obj_or_ex
    obj = _result_target(ex)
    me = obj.data
    full = np.zeros((ex.n_vertices, 4), np.float32)
    full[:, 3] = 1.0
    full[ex.vmap, :3] = colors
    old = me.color_attributes.get(name)
    if old is not None:
        me.color_attributes.remove(old)
    attr = me.color_attributes.new(name=name, type='FLOAT_COLOR', domain='POINT')
    attr.data.foreach_set("color_srgb", full.ravel())
    me.color_attributes.active_color = attr
    me.color_attributes.render_color_index = me.color_attributes.active_color_index
    me.update()
    return obj, attr


def new_image(name, texture):
    """A packed sRGB image from an (H, W, 3) uint8 array, row 0 at the top."""
    h, w, _ = texture.shape
    img = bpy.data.images.new(name, width=w, height=h, alpha=False)
    rgba = np.ones((h, w, 4), np.float32)
    rgba[:, :, :3] = texture[::-1].astype(np.float32) / 255.0
    img.pixels.foreach_set(rgba.ravel())
    img.file_format = 'PNG'
    img.pack()
    return img


def new_map_images(obj, maps):
    """Each baked map (name -> (H, W) or (H, W, 3) floats in [0, 1], row 0 at the top) as a new
    packed float image named `MeshMatch <map> <object>`, non-colour data."""
    images = []
    for name, arr in maps.items():
        arr = np.asarray(arr, np.float32)
        h, w = arr.shape[:2]
        img = bpy.data.images.new(f"MeshMatch {name} {obj.name}", width=w, height=h,
                                  alpha=False, float_buffer=True)
        img.colorspace_settings.name = 'Non-Color'
        rgba = np.ones((h, w, 4), np.float32)
        rgba[:, :, :3] = (arr if arr.ndim == 3 else arr[:, :, None])[::-1]
        img.pixels.foreach_set(rgba.ravel())
        img.file_format = 'OPEN_EXR'
        img.pack()
        images.append(img)
    return images


def write_texture(ex, result, name="MeshMatch"):
    """The result's texture as a new image wired into the object's material (Base Color, through
    the UV map it was baked in); a mesh without UVs gets the result's generated atlas as a new UV
    map. The material is copied first when other objects share it."""
    obj = _result_target(ex)
    me = obj.data
    uv_name = ex.uv_name
    if uv_name is None or me.uv_layers.get(uv_name) is None:
        layer = me.uv_layers.new(name=f"{name} UV")
        buf = np.zeros((len(me.loops), 2), np.float32)
        buf[ex.loops] = result.uvs
        layer.uv.foreach_set("vector", buf.ravel())
        uv_name = layer.name
    img = new_image(f"{name} {obj.name}", result.texture)
    mat = obj.active_material
    if mat is None:
        mat = bpy.data.materials.new(f"{name} {obj.name}")
        if len(obj.material_slots) == 0:
            me.materials.append(mat)
        else:
            obj.material_slots[obj.active_material_index].material = mat
    elif mat.users > 1:
        mat = mat.copy()
        obj.material_slots[obj.active_material_index].material = mat
    if not _uses_nodes(mat):
        mat.use_nodes = True
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    bsdf = next((nd for nd in nodes if nd.type == 'BSDF_PRINCIPLED'), None)
    if bsdf is None:
        bsdf = nodes.new("ShaderNodeBsdfPrincipled")
        out = next((nd for nd in nodes if nd.type == 'OUTPUT_MATERIAL'), None)
        if out is None:
            out = nodes.new("ShaderNodeOutputMaterial")
        links.new(bsdf.outputs["BSDF"], out.inputs["Surface"])
    tex = nodes.new("ShaderNodeTexImage")
    tex.image = img
    tex.label = name
    tex.location = (bsdf.location.x - 400, bsdf.location.y)
    uvnode = nodes.new("ShaderNodeUVMap")
    uvnode.uv_map = uv_name
    uvnode.location = (tex.location.x - 250, tex.location.y)
    links.new(uvnode.outputs["UV"], tex.inputs["Vector"])
    links.new(tex.outputs["Color"], bsdf.inputs["Base Color"])
    nodes.active = tex
    return obj, img


def apply_surface_result(ex, result, name):
    """A colour result where Blender users look for it: an image texture when the result has
    one, else a colour attribute."""
    if result.texture is not None and result.uvs is not None:
        return write_texture(ex, result, name)
    if result.colors is None:
        raise meshmatch.MeshMatchError("the result carries no colours")
    return write_colors(ex, result.colors, name)


def new_mesh_object(name, mesh, collection, element_ids=None):
    """A new object from a meshmatch mesh in world space (elements of a quilt: `element_ids`
    per vertex as an integer point attribute `element`)."""
    me = bpy.data.meshes.new(name)
    v = mesh.vertices
    f = mesh.faces
    me.vertices.add(len(v))
    me.vertices.foreach_set("co", v.ravel())
    me.loops.add(f.size)
    me.loops.foreach_set("vertex_index", f.ravel())
    me.polygons.add(len(f))
    me.polygons.foreach_set("loop_start", np.arange(0, f.size, 3, dtype=np.int32))
    me.polygons.foreach_set("loop_total", np.full(len(f), 3, np.int32))
    if element_ids is not None:
        attr = me.attributes.new("element", 'INT', 'POINT')
        attr.data.foreach_set("value", np.asarray(element_ids, np.int32))
    me.update(calc_edges=True)
    me.validate()
    obj = bpy.data.objects.new(name, me)
    collection.objects.link(obj)
    return obj


def new_curve_object(name, curves, collection):
    """Salient curves as one curve object of poly splines, in world space."""
    cu = bpy.data.curves.new(name, 'CURVE')
    cu.dimensions = '3D'
    for c in curves:
        pts = c["points"]
        if len(pts) < 2:
            continue
        sp = cu.splines.new('POLY')
        sp.points.add(len(pts) - 1)
        co = np.ones((len(pts), 4), np.float32)
        co[:, :3] = pts
        sp.points.foreach_set("co", co.ravel())
        sp.use_cyclic_u = bool(c["closed"])
    obj = bpy.data.objects.new(name, cu)
    collection.objects.link(obj)
    return obj
