"""The MeshMatch operators. Each reads the scene on the main thread, runs its meshmatch calls
(one per target) on a background thread while a modal handler shows progress in the status bar
and Esc cancels, then writes the results back: one undo step. Run from a script (or in
background mode) the same calls run in `execute`, on the calling thread."""

import re

import bpy
import numpy as np
from bpy.props import BoolProperty, EnumProperty, FloatProperty, IntProperty, StringProperty

import meshmatch

from . import convert
from .jobs import Job

PAIR_NAME = re.compile(r"^(?P<key>.+)[._ ](?P<side>source|target)$", re.IGNORECASE)


class Task:
    """One meshmatch call and what to do with its result."""

    def __init__(self, label, fn, args, kwargs, apply):
        self.label = label
        self.fn = fn
        self.args = args
        self.kwargs = kwargs
        self.apply = apply

    def job(self):
        return Job(self.fn, *self.args, **self.kwargs)


def mesh_objects(context, exclude=None):
    return [
        o
        for o in context.selected_objects
        if o.type == 'MESH' and o is not exclude
    ]


def pairs_from_empties(source_ex, target_ex):
    """Correspondences from empties named as pairs: `<key>.source` and `<key>.target` (or with
    `_` or a space before the side), each at the nearest vertex of its mesh."""
    sides = {}
    for o in bpy.data.objects:
        if o.type != 'EMPTY':
            continue
        m = PAIR_NAME.match(o.name)
        if m:
            sides.setdefault(m["key"], {})[m["side"].lower()] = o
    pairs = []
    for key in sorted(sides):
        s = sides[key]
        if "source" in s and "target" in s:
            a = convert.nearest_vertex(source_ex, s["source"].matrix_world.translation)
            b = convert.nearest_vertex(target_ex, s["target"].matrix_world.translation)
            pairs.append((a, b))
    return pairs


def selected_vertices(ex):
    """The meshmatch vertices of `ex` whose Blender vertices are selected."""
    me = ex.obj.data
    if me is None or len(me.vertices) != ex.n_vertices:
        return []
    sel = np.zeros(len(me.vertices), bool)
    me.vertices.foreach_get("select", sel)
    return [i for i, v in enumerate(ex.vmap) if sel[v]]


class MeshMatchOperator(bpy.types.Operator):
    """Shared modal machinery: subclasses implement `tasks(context)`."""

    bl_options = {'REGISTER', 'UNDO'}

    _timer = None
    _queue = None
    _job = None
    _task = None
    _done = 0

    def tasks(self, context):
        raise NotImplementedError

    def _prepare(self, context):
        if context.mode != 'OBJECT':
            bpy.ops.object.mode_set(mode='OBJECT')
        # World matrices of objects a script just moved (pair empties) are current.
        context.view_layer.update()
        try:
            return self.tasks(context)
        except meshmatch.MeshMatchError as e:
            self.report({'ERROR'}, str(e))
            return None

    def execute(self, context):
        tasks = self._prepare(context)
        if tasks is None:
            return {'CANCELLED'}
        for t in tasks:
            job = t.job().run_here()
            if job.error is not None:
                self.report({'ERROR'}, f"{t.label}: {job.error}")
                return {'CANCELLED'}
            t.apply(context, job.result)
        return {'FINISHED'}

    def invoke(self, context, event):
        tasks = self._prepare(context)
        if tasks is None:
            return {'CANCELLED'}
        self._queue = list(tasks)
        self._done = 0
        self._results = []
        self._total = len(tasks)
        wm = context.window_manager
        wm.progress_begin(0, 1000)
        self._next()
        self._timer = wm.event_timer_add(0.1, window=context.window)
        wm.modal_handler_add(self)
        return {'RUNNING_MODAL'}

    def _next(self):
        self._task = self._queue.pop(0)
        self._job = self._task.job().start()

    def _finish(self, context):
        wm = context.window_manager
        if self._timer is not None:
            wm.event_timer_remove(self._timer)
            self._timer = None
        wm.progress_end()
        if context.workspace is not None:
            context.workspace.status_text_set(None)

    def modal(self, context, event):
        if event.type == 'ESC':
            self._job.cancel()
            return {'RUNNING_MODAL'}
        if event.type != 'TIMER':
            return {'PASS_THROUGH'}
        job = self._job
        frac = (self._done + job.fraction) / self._total
        context.window_manager.progress_update(int(frac * 1000))
        if context.workspace is not None:
            context.workspace.status_text_set(
                f"MeshMatch {self._task.label}: {job.stage} {100 * frac:.0f}%  (Esc to cancel)"
            )
        if not job.done:
            return {'RUNNING_MODAL'}
        if job.error is not None:
            self._finish(context)
            if isinstance(job.error, meshmatch.Cancelled):
                self.report({'WARNING'}, f"MeshMatch {self._task.label}: cancelled")
            else:
                self.report({'ERROR'}, f"{self._task.label}: {job.error}")
            return {'CANCELLED'}
        self._results.append((self._task, job.result))
        self._done += 1
        if self._queue:
            self._next()
            return {'RUNNING_MODAL'}
        self._finish(context)
        # Every target is written only once all have finished: a cancel changes nothing.
        for task, result in self._results:
            task.apply(context, result)
        return {'FINISHED'}


def solve_props(cls):
    """The MeshMatch solver settings shared by transfer and complete."""
    cls.__annotations__.update(
        vertices=IntProperty(
            name="Working vertices", default=64000, min=128, max=4000000,
            description="Working resolution: meshes are refined to about this many vertices"),
        iterations=IntProperty(name="Iterations", default=5, min=0, max=1000,
                               description="EM iterations per level at most"),
        seed=IntProperty(name="Seed", default=0, min=0),
        texture_size=IntProperty(
            name="Texture size", default=0, min=0, max=8192,
            description="Pixels per side of a baked texture (0: the target's own texture's size, "
                        "else 2048)"),
    )
    return cls


def _solve_kwargs(op):
    """The solver settings of an operator with `solve_props`, as keyword arguments."""
    return dict(vertices=op.vertices, iterations=op.iterations, seed=op.seed,
                texture_size=_texture_size(op.texture_size))


def _texture_size(v):
    return None if v == 0 else v


@solve_props
class MESHMATCH_OT_transfer(MeshMatchOperator):
    """Transfer the active object's texture or colours to the other selected meshes (MeshMatch).
    Correspondences: empties named <key>.source / <key>.target, or one selected vertex on the
    source and the selected vertices on a target"""

    bl_idname = "meshmatch.transfer"
    bl_label = "Transfer"

    __annotations__ = {}

    def tasks(self, context):
        src_obj = context.active_object
        if src_obj is None or src_obj.type != 'MESH':
            raise meshmatch.MeshMatchError("make the source mesh the active object")
        targets = mesh_objects(context, exclude=src_obj)
        if not targets:
            raise meshmatch.MeshMatchError("select the target meshes as well as the source")
        dg = context.evaluated_depsgraph_get()
        src = convert.extract(src_obj, dg)
        if src.mesh.colors is None and src.mesh.texture is None:
            raise meshmatch.MeshMatchError(
                f"{src_obj.name}: has no colour attribute and no image texture on its Base Color")
        tasks = []
        for t in targets:
            ex = convert.extract(t, dg, colors=False, texture=False)
            pairs = pairs_from_empties(src, ex)
            s_sel, t_sel = selected_vertices(src), selected_vertices(ex)
            if len(s_sel) == 1 and t_sel:
                pairs.append((s_sel[0], t_sel))
            tasks.append(Task(
                f"transfer to {t.name}", meshmatch.transfer,
                (src.mesh, ex.mesh, pairs or None), _solve_kwargs(self),
                lambda ctx, r, ex=ex: convert.apply_surface_result(ex, r, "MeshMatch")))
        return tasks


@solve_props
class MESHMATCH_OT_complete(MeshMatchOperator):
    """Complete the active mesh's painted colour attribute by example: vertices left in the clay
    colour (the most frequent one) are synthesised from the painted ones"""

    bl_idname = "meshmatch.complete"
    bl_label = "Complete"

    __annotations__ = {}

    def tasks(self, context):
        obj = context.active_object
        if obj is None or obj.type != 'MESH':
            raise meshmatch.MeshMatchError("make the painted mesh the active object")
        ex = convert.extract(obj, context.evaluated_depsgraph_get(), texture=False)
        if ex.mesh.colors is None:
            raise meshmatch.MeshMatchError(
                f"{obj.name}: paint a colour attribute first (Vertex Paint or Texture Paint)")
        kwargs = dict(painted=ex.mesh, **_solve_kwargs(self))
        return [Task(f"complete {obj.name}", meshmatch.complete, (ex.mesh,), kwargs,
                     lambda ctx, r: convert.apply_surface_result(ex, r, "MeshMatch Complete"))]


class MESHMATCH_OT_weather(MeshMatchOperator):
    """Learn the active object's weathering (dirt, moss) from its colours and geometry and apply
    it to the other selected meshes by theirs (Mertens et al. 2006)"""

    bl_idname = "meshmatch.weather"
    bl_label = "Weather"

    vertices: IntProperty(name="Working vertices", default=100000, min=0, max=4000000)
    rays: IntProperty(name="Rays", default=64, min=1, max=4096,
                      description="Occlusion rays per vertex")
    clusters: IntProperty(name="Clusters", default=50, min=1, max=1000)
    up: EnumProperty(name="Up", items=[('z', "Z", "Blender's up axis"), ('y', "Y", "")],
                     default='z')
    seed: IntProperty(name="Seed", default=0, min=0)
    texture_size: IntProperty(name="Texture size", default=1024, min=1, max=8192)

    def tasks(self, context):
        src_obj = context.active_object
        if src_obj is None or src_obj.type != 'MESH':
            raise meshmatch.MeshMatchError("make the weathered source mesh the active object")
        targets = mesh_objects(context, exclude=src_obj)
        if not targets:
            raise meshmatch.MeshMatchError("select the meshes to weather as well as the source")
        dg = context.evaluated_depsgraph_get()
        src = convert.extract(src_obj, dg)
        tasks = []
        for t in targets:
            ex = convert.extract(t, dg, colors=False, texture=False)
            kwargs = dict(vertices=self.vertices, rays=self.rays, clusters=self.clusters,
                          up=self.up, seed=self.seed, texture_size=self.texture_size)
            tasks.append(Task(f"weather {t.name}", meshmatch.weather, (src.mesh, ex.mesh), kwargs,
                              lambda ctx, r, ex=ex: convert.apply_surface_result(
                                  ex, r, "MeshMatch Weather")))
        return tasks


class MESHMATCH_OT_feature_maps(MeshMatchOperator):
    """Bake the selected meshes' feature maps (ambient occlusion, curvature, cavity, thickness,
    world-space normal, height) into new float images through their active UV maps"""

    bl_idname = "meshmatch.feature_maps"
    bl_label = "Bake Feature Maps"

    texture_size: IntProperty(name="Texture size", default=2048, min=16, max=8192)
    radius: FloatProperty(name="Curvature radius", default=0.01, min=0.0001, max=0.5,
                          description="Fraction of the bounding-box diagonal")
    cavity_radius: FloatProperty(name="Cavity radius", default=0.003, min=0.0001, max=0.5,
                                 description="Fraction of the bounding-box diagonal")
    rays: IntProperty(name="Rays", default=64, min=1, max=4096,
                      description="Rays per vertex for occlusion and thickness")
    up: EnumProperty(name="Up", items=[('z', "Z", "Blender's up axis"), ('y', "Y", "")],
                     default='z')
    seed: IntProperty(name="Seed", default=0, min=0)

    def tasks(self, context):
        objs = mesh_objects(context)
        if not objs:
            raise meshmatch.MeshMatchError("select the meshes to bake")
        dg = context.evaluated_depsgraph_get()
        tasks = []
        for o in objs:
            ex = convert.extract(o, dg, colors=False, texture=False)
            if ex.uv_name is None:
                raise meshmatch.MeshMatchError(
                    f"{o.name}: the maps are baked through a UV map: add one (UV > Smart UV "
                    "Project) first")
            kwargs = dict(texture_size=self.texture_size, radius=self.radius,
                          cavity_radius=self.cavity_radius, rays=self.rays, up=self.up,
                          seed=self.seed)
            tasks.append(Task(f"feature maps of {o.name}", meshmatch.feature_maps,
                              (ex.mesh, "all"), kwargs,
                              lambda ctx, r, o=o: convert.new_map_images(o, r)))
        return tasks


class MESHMATCH_OT_synthesize(MeshMatchOperator):
    """Synthesize a texture from an image over the selected meshes (Wei and Levoy 2001)"""

    bl_idname = "meshmatch.synthesize"
    bl_label = "Synthesize"

    image: StringProperty(name="Image", description="Exemplar: an image datablock's name")
    filepath: StringProperty(name="File", subtype='FILE_PATH',
                             description="Exemplar image file (when no image is named)")
    texture_size: IntProperty(name="Texture size", default=2048, min=1, max=8192)
    scale: FloatProperty(name="Scale", default=0.0, min=0.0,
                         description="Scene units spanned by the exemplar's width (0: a quarter "
                                     "of the mesh's diagonal)")
    orientation: EnumProperty(name="Orientation", default='auto', items=[
        ('auto', "Auto", "From the exemplar's anisotropy"),
        ('random', "Random", "Isotropic textures"),
        ('up', "Up", "Projected +Y"),
        ('relax2', "Stripes", "A smooth 2-fold field"),
        ('relax4', "Grid", "A smooth 4-fold field"),
        ('features', "Features", "Along the mesh's salient curves")])
    align_features: BoolProperty(
        name="Align features", default=False,
        description="Put the exemplar's principal line on the mesh's crest lines and creases "
                    "(feature-aligned texturing, Xu et al. 2009; slower)")
    seed: IntProperty(name="Seed", default=0, min=0)

    def tasks(self, context):
        if self.image:
            img = bpy.data.images.get(self.image)
            if img is None:
                raise meshmatch.MeshMatchError(f"no image named {self.image}")
            exemplar = convert.image_to_array(img, keep_alpha=True)
        elif self.filepath:
            exemplar = bpy.path.abspath(self.filepath)
        else:
            raise meshmatch.MeshMatchError("choose an exemplar image")
        targets = mesh_objects(context)
        if not targets:
            raise meshmatch.MeshMatchError("select the meshes to texture")
        dg = context.evaluated_depsgraph_get()
        tasks = []
        for t in targets:
            ex = convert.extract(t, dg, colors=False, texture=False)
            kwargs = dict(texture_size=self.texture_size, orientation=self.orientation,
                          align_features=self.align_features, seed=self.seed,
                          scale=self.scale if self.scale > 0 else None)
            tasks.append(Task(f"synthesize on {t.name}", meshmatch.synthesize, (exemplar, ex.mesh),
                              kwargs, lambda ctx, r, ex=ex: convert.write_texture(
                                  ex, r, "MeshMatch Synth")))
        return tasks


SWATCHES = [
    ('chain', "Chain mail", ""), ('weave', "Weave", ""), ('nuts', "Nuts", ""),
    ('studs', "Studs", ""), ('scales', "Scales", ""),
    ('OBJECT', "Object", "The swatch object: its separate parts are the elements, over its XY "
                         "plane, Z up"),
]


class MESHMATCH_OT_quilt(MeshMatchOperator):
    """Cover the active mesh with 3D elements from a swatch (mesh quilting, Zhou et al. 2006);
    the elements become a new object with an `element` attribute"""

    bl_idname = "meshmatch.quilt"
    bl_label = "Quilt"

    swatch: EnumProperty(name="Swatch", items=SWATCHES, default='chain')
    swatch_object: StringProperty(name="Swatch object")
    swatch_size: FloatProperty(name="Swatch size", default=0.0, min=0.0,
                               description="Swatch width in scene units (0: a tenth of the "
                                           "mesh's diagonal)")
    seed: IntProperty(name="Seed", default=1, min=0)

    def tasks(self, context):
        base_obj = context.active_object
        if base_obj is None or base_obj.type != 'MESH':
            raise meshmatch.MeshMatchError("make the base mesh the active object")
        dg = context.evaluated_depsgraph_get()
        base = convert.extract(base_obj, dg, colors=False, texture=False)
        if self.swatch == 'OBJECT':
            sw = bpy.data.objects.get(self.swatch_object)
            if sw is None or sw.type != 'MESH':
                raise meshmatch.MeshMatchError("choose a swatch mesh object")
            swatch = convert.extract(sw, dg, colors=False, texture=False).mesh
        else:
            swatch = self.swatch
        kwargs = dict(seed=self.seed,
                      swatch_size=self.swatch_size if self.swatch_size > 0 else None)
        collection = base_obj.users_collection[0] if base_obj.users_collection else \
            context.scene.collection

        def apply(ctx, r):
            elements, ids = r
            convert.new_mesh_object(f"{base_obj.name} quilt", elements, collection, ids)

        return [Task(f"quilt {base_obj.name}", meshmatch.quilt, (base.mesh, swatch), kwargs,
                     apply)]


class MESHMATCH_OT_curves(MeshMatchOperator):
    """The active mesh's salient curves (crest lines and sharp creases) as a curve object"""

    bl_idname = "meshmatch.curves"
    bl_label = "Curves"

    threshold: FloatProperty(name="Threshold", default=1.0, min=0.0,
                             description="Minimum strength of a curve")
    crease_angle: FloatProperty(name="Crease angle", default=40.0, min=0.0, max=180.0)
    creases_only: BoolProperty(name="Creases only", default=False)

    def tasks(self, context):
        obj = context.active_object
        if obj is None or obj.type != 'MESH':
            raise meshmatch.MeshMatchError("make a mesh the active object")
        ex = convert.extract(obj, context.evaluated_depsgraph_get(), colors=False, texture=False)
        kwargs = dict(threshold=self.threshold, crease_angle=self.crease_angle,
                      creases_only=self.creases_only)
        collection = obj.users_collection[0] if obj.users_collection else context.scene.collection
        return [Task(f"curves of {obj.name}", meshmatch.curves, (ex.mesh,), kwargs,
                     lambda ctx, r: convert.new_curve_object(f"{obj.name} curves", r, collection))]


class MESHMATCH_OT_add_pair(bpy.types.Operator):
    """Mark a correspondence: in Edit Mode, one selected vertex on the active (source) mesh and
    one on another mesh become a pair of empties <key>.source / <key>.target"""

    bl_idname = "meshmatch.add_pair"
    bl_label = "Add Pair"
    bl_options = {'REGISTER', 'UNDO'}

    def execute(self, context):
        src = context.active_object
        others = [o for o in context.objects_in_mode if o is not src] if context.mode == 'EDIT_MESH' \
            else []
        if src is None or not others:
            self.report({'ERROR'}, "edit the source and a target together (Tab with both selected)")
            return {'CANCELLED'}
        bpy.ops.object.mode_set(mode='OBJECT')
        points = []
        for o in (src, others[0]):
            sel = [v.co for v in o.data.vertices if v.select]
            if len(sel) != 1:
                bpy.ops.object.mode_set(mode='EDIT')
                self.report({'ERROR'}, f"{o.name}: select exactly one vertex ({len(sel)} selected)")
                return {'CANCELLED'}
            points.append(o.matrix_world @ sel[0])
        n = 1
        while bpy.data.objects.get(f"Pair {n}.source") is not None:
            n += 1
        for side, p in zip(("source", "target"), points):
            e = bpy.data.objects.new(f"Pair {n}.{side}", None)
            e.empty_display_type = 'SPHERE'
            e.empty_display_size = 0.02
            e.location = p
            context.scene.collection.objects.link(e)
        bpy.ops.object.mode_set(mode='EDIT')
        return {'FINISHED'}


classes = (
    MESHMATCH_OT_transfer,
    MESHMATCH_OT_complete,
    MESHMATCH_OT_weather,
    MESHMATCH_OT_feature_maps,
    MESHMATCH_OT_synthesize,
    MESHMATCH_OT_quilt,
    MESHMATCH_OT_curves,
    MESHMATCH_OT_add_pair,
)
