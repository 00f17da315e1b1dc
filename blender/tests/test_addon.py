"""The Blender add-on in real Blender (bpy as a Python module, background mode): registered from
blender/meshmatch, each operator run on shared meshes imported with their file coordinates, the
results checked against the CLI's on the same files, and Blender's own undo taking each result
back (test_undo_takes_each_result_back).

Meshes are imported with up Z and forward Y (no axis conversion), so Blender's world coordinates
are the file's and the add-on's world-space meshes equal what the CLI loads. Background mode has
no event loop, so operators run through `execute`; the modal path's job (thread, progress,
cancel) is tested on its own."""

import importlib.util
import os
import subprocess
import sys
import threading
from pathlib import Path

import bpy
import numpy as np
import pytest

import meshmatch

ROOT = Path(__file__).resolve().parents[2]
DATA = Path(os.environ.get("MESHMATCH_DATA", ROOT.parent / "shared" / "data"))
FAST = dict(vertices=3000, iterations=2)
FAST_FLAGS = ["--vertices", "3000", "--iterations", "2"]
# The CLI's PLY stores 8-bit colours (0.5/255); a float colour attribute stores linear values, and
# Blender's sRGB conversion through `color_srgb` round-trips within 1.2e-4 (measured on random
# colours).
TOL = 0.5 / 255 + 2e-4


def load_addon():
    path = ROOT / "blender" / "meshmatch"
    spec = importlib.util.spec_from_file_location(
        "meshmatch_addon", path / "__init__.py", submodule_search_locations=[str(path)]
    )
    mod = importlib.util.module_from_spec(spec)
    sys.modules["meshmatch_addon"] = mod
    spec.loader.exec_module(mod)
    return mod


ADDON = load_addon()


@pytest.fixture(scope="module", autouse=True)
def registered():
    ADDON.register()
    yield
    ADDON.unregister()


@pytest.fixture(autouse=True)
def empty_scene():
    bpy.ops.wm.read_homefile(use_empty=True)
    yield


@pytest.fixture(scope="session")
def cli():
    exe = Path(os.environ.get("MESHMATCH_CLI", ROOT / "target" / "release" / "meshmatch"))
    if not exe.is_file():
        pytest.fail(f"{exe}: build the CLI first (cargo build --release) or set MESHMATCH_CLI")

    def run(*args):
        r = subprocess.run([str(exe), *map(str, args)], capture_output=True, text=True)
        assert r.returncode == 0, f"meshmatch {' '.join(map(str, args))}: {r.stderr}"

    return run


def single(tmp_path, rel):
    """`rel` as the add-on sees it once imported: its coordinates in single precision, written
    as binary PLY (single precision; the vertices, UVs and texture kept), so that the CLI reads
    the same numbers. On the OBJ itself the CLI reads the file's digits in double precision
    (its working units, docs/formats.md#units), which a Blender mesh no longer has."""
    out = tmp_path / (Path(rel).stem + "_single.ply")
    meshmatch.load(DATA / rel).save(out)
    return out


def import_obj(rel):
    """Import an OBJ without axis conversion: world coordinates are the file's."""
    before = set(bpy.data.objects)
    bpy.ops.wm.obj_import(filepath=str(DATA / rel), forward_axis='Y', up_axis='Z')
    new = [o for o in bpy.data.objects if o not in before]
    assert len(new) == 1
    return new[0]


def select(active, *others):
    bpy.ops.object.select_all(action='DESELECT')
    for o in (active, *others):
        o.select_set(True)
    bpy.context.view_layer.objects.active = active


def attribute_colors(obj, name):
    attr = obj.data.color_attributes[name]
    assert attr.domain == 'POINT'
    buf = np.empty(len(attr.data) * 4, np.float32)
    attr.data.foreach_get("color_srgb", buf)
    return buf.reshape(-1, 4)[:, :3]


def image_pixels(img):
    w, h = img.size
    buf = np.empty(w * h * 4, np.float32)
    img.pixels.foreach_get(buf)
    return np.rint(buf.reshape(h, w, 4)[::-1, :, :3] * 255).astype(np.uint8)


def base_color_image(obj):
    from meshmatch_addon import convert

    return convert.base_color_image(obj)


def test_the_addon_registers_its_operators_and_panel():
    for op in ("transfer", "complete", "weather", "synthesize", "quilt", "curves", "add_pair",
               "feature_maps"):
        assert hasattr(bpy.ops.meshmatch, op)
        assert getattr(bpy.ops.meshmatch, op).poll() in (True, False)
    assert hasattr(bpy.types, "VIEW3D_PT_meshmatch")
    assert hasattr(bpy.context.scene, "meshmatch")


def test_the_manifest_is_a_blender_extension():
    import tomllib

    m = tomllib.loads((ROOT / "blender" / "meshmatch" / "blender_manifest.toml").read_text())
    assert m["id"] == "meshmatch" and m["type"] == "add-on"
    assert tuple(map(int, m["blender_version_min"].split("."))) >= (4, 2, 0)


def test_each_operator_is_one_undo_step():
    # Blender pushes one undo step when an operator with the UNDO option finishes in the UI;
    # operators called from a script in background mode push none (test_undo_takes_each_result
    # _back pushes the step itself).
    for op in ("transfer", "complete", "weather", "synthesize", "quilt", "curves", "add_pair",
               "feature_maps"):
        cls = getattr(bpy.types, f"MESHMATCH_OT_{op}")
        assert {'REGISTER', 'UNDO'} <= set(cls.bl_options), op


def undone(run, state):
    """Run an operator between two undo steps as the UI does (one step before, one pushed when
    it finishes); Blender's undo must bring back `state()` as it was, and redo the result."""
    bpy.ops.ed.undo_push(message="before")
    before = state()
    assert run() == {'FINISHED'}
    bpy.ops.ed.undo_push(message="MeshMatch")
    after = state()
    assert after != before, "the operator changed nothing"
    bpy.ops.ed.undo()
    assert state() == before
    bpy.ops.ed.redo()
    assert state() == after


def test_undo_takes_each_result_back():
    # a colour attribute on the target (its mesh data), the source untouched
    spot = import_obj("spot/spot.obj")
    penguin = import_obj("penguin/penguin.obj")
    select(spot, penguin)

    def attributes():
        return {
            o.name: sorted(o.data.color_attributes.keys()) for o in bpy.data.objects
        }

    undone(lambda: bpy.ops.meshmatch.transfer(**FAST), attributes)
    # a new image wired into the target's material
    bpy.ops.wm.read_homefile(use_empty=True)
    src = import_obj("spot/spot.obj")
    tgt = import_obj("spot/spot.obj")
    select(src, tgt)
    name = tgt.name

    def texture():
        img = base_color_image(bpy.data.objects[name])
        return (sorted(i.name for i in bpy.data.images), img.name if img else None)

    undone(lambda: bpy.ops.meshmatch.transfer(texture_size=64, **FAST), texture)
    # new objects: a quilt, curves
    bpy.ops.wm.read_homefile(use_empty=True)
    cat = import_obj("cat/cat.obj")

    def objects():
        return sorted((o.name, o.type) for o in bpy.data.objects)

    select(cat)
    undone(lambda: bpy.ops.meshmatch.curves(), objects)
    select(bpy.data.objects["cat"])
    undone(lambda: bpy.ops.meshmatch.quilt(swatch='studs'), objects)


def test_transfer_writes_the_clis_colours_as_a_colour_attribute(tmp_path, cli):
    out = tmp_path / "cli.ply"
    cli("transfer", "--source", single(tmp_path, "spot/spot.obj"), "--target",
        single(tmp_path, "penguin/penguin.obj"), "--out", out, *FAST_FLAGS)
    spot = import_obj("spot/spot.obj")
    penguin = import_obj("penguin/penguin.obj")
    select(spot, penguin)
    assert bpy.ops.meshmatch.transfer(**FAST) == {'FINISHED'}
    got = attribute_colors(penguin, "MeshMatch")
    want = meshmatch.load(out).colors
    assert got.shape == want.shape
    assert np.abs(got - want).max() <= TOL
    # The source is untouched.
    assert "MeshMatch" not in spot.data.color_attributes


def test_transfer_to_a_uv_mesh_wires_a_new_image_of_the_clis_texture(tmp_path, cli):
    out = tmp_path / "cli.glb"
    spot_single = single(tmp_path, "spot/spot.obj")
    cli("transfer", "--source", spot_single, "--target", spot_single,
        "--out", out, "--texture-size", "256", *FAST_FLAGS)
    src = import_obj("spot/spot.obj")
    tgt = import_obj("spot/spot.obj")
    select(src, tgt)
    n_images = len(bpy.data.images)
    assert bpy.ops.meshmatch.transfer(texture_size=256, **FAST) == {'FINISHED'}
    assert len(bpy.data.images) == n_images + 1
    img = base_color_image(tgt)
    assert img is not None and img.name.startswith("MeshMatch") and img.packed_file is not None
    assert tuple(img.size) == (256, 256)
    np.testing.assert_array_equal(image_pixels(img), meshmatch.load(out).texture)
    # The source keeps its own material and texture.
    assert base_color_image(src).name == "spot_texture.png"


def test_complete_fills_the_clay_from_the_painted_colours_as_the_cli_does(tmp_path, cli):
    penguin = import_obj("penguin/penguin.obj")
    me = penguin.data
    n = len(me.vertices)
    co = np.empty(n * 3, np.float32)
    me.vertices.foreach_get("co", co)
    co = co.reshape(n, 3)
    # Paint stripes on the lower third; the rest stays clay grey.
    painted = np.full((n, 3), 128, np.uint8)
    low = co[:, 1] < np.quantile(co[:, 1], 0.33)
    stripe = (np.floor(co[:, 0] * 20) % 2 == 0)
    painted[low & stripe] = (200, 40, 30)
    painted[low & ~stripe] = (240, 220, 60)
    attr = me.color_attributes.new("Paint", 'BYTE_COLOR', 'POINT')
    rgba = np.ones((n, 4), np.float32)
    rgba[:, :3] = painted / 255.0
    attr.data.foreach_set("color_srgb", rgba.ravel())
    me.color_attributes.active_color = attr
    meshmatch.load(DATA / "penguin/penguin.obj").with_colors(painted).save(tmp_path / "p.ply")
    out = tmp_path / "cli.ply"
    cli("complete", "--mesh", DATA / "penguin/penguin.obj", "--painted", tmp_path / "p.ply",
        "--out", out, *FAST_FLAGS)
    select(penguin)
    assert bpy.ops.meshmatch.complete(**FAST) == {'FINISHED'}
    got = attribute_colors(penguin, "MeshMatch Complete")
    assert np.abs(got - meshmatch.load(out).colors).max() <= TOL
    # Painted vertices keep their colours.
    assert np.abs(got[low] - painted[low] / 255.0).max() <= TOL


def test_weather_writes_the_clis_colours(tmp_path, cli):
    out = tmp_path / "cli.ply"
    cli("weather", "--source", single(tmp_path, "spot/spot.obj"), "--target",
        single(tmp_path, "penguin/penguin.obj"), "--out", out, "--vertices", "4000", "--rays", "16")
    spot = import_obj("spot/spot.obj")
    penguin = import_obj("penguin/penguin.obj")
    select(spot, penguin)
    assert bpy.ops.meshmatch.weather(vertices=4000, rays=16, up='y') == {'FINISHED'}
    got = attribute_colors(penguin, "MeshMatch Weather")
    assert np.abs(got - meshmatch.load(out).colors).max() <= TOL


def test_feature_maps_become_float_images_equal_to_the_packages_bake():
    from meshmatch_addon import convert

    spot = import_obj("spot/spot.obj")
    select(spot)
    assert bpy.ops.meshmatch.feature_maps(texture_size=64, rays=8, up='z') == {'FINISHED'}
    ex = convert.extract(spot, bpy.context.evaluated_depsgraph_get(), colors=False,
                         texture=False)
    want = meshmatch.feature_maps(ex.mesh, "all", texture_size=64, rays=8, up='z')
    assert set(want) == {"ao", "curvature", "cavity", "thickness", "normal", "height"}
    for name, arr in want.items():
        img = bpy.data.images[f"MeshMatch {name} {spot.name}"]
        assert tuple(img.size) == (64, 64) and img.is_float and img.packed_file is not None
        assert img.colorspace_settings.name == 'Non-Color'
        buf = np.empty(64 * 64 * 4, np.float32)
        img.pixels.foreach_get(buf)
        got = buf.reshape(64, 64, 4)[::-1, :, :3]
        arr = np.asarray(arr)
        exp = arr if arr.ndim == 3 else np.repeat(arr[:, :, None], 3, axis=2)
        assert np.abs(got - exp).max() < 1e-5, name


def test_feature_maps_refuse_a_mesh_without_uvs_in_one_line():
    bpy.ops.mesh.primitive_cube_add()
    cube = bpy.context.active_object
    while cube.data.uv_layers:
        cube.data.uv_layers.remove(cube.data.uv_layers[0])
    cube.data.update()
    select(cube)
    with pytest.raises(RuntimeError, match="baked through a UV map"):
        bpy.ops.meshmatch.feature_maps(texture_size=64, rays=8)
    assert not [i for i in bpy.data.images if i.name.startswith("MeshMatch ")]


def test_synthesize_from_an_image_bakes_the_clis_texture(tmp_path, cli):
    ex = DATA / "textures" / "5.png"
    out = tmp_path / "cli.glb"
    cli("synth", "--exemplar", ex, "--target", single(tmp_path, "spot/spot.obj"), "--out", out,
        "--texture-size", "256")
    spot = import_obj("spot/spot.obj")
    img = bpy.data.images.load(str(ex))
    select(spot)
    assert bpy.ops.meshmatch.synthesize(image=img.name, texture_size=256) == {'FINISHED'}
    result = base_color_image(spot)
    assert tuple(result.size) == (256, 256)
    np.testing.assert_array_equal(image_pixels(result), meshmatch.load(out).texture)


def test_quilt_makes_an_object_of_whole_elements(tmp_path, cli):
    out = tmp_path / "q.ply"
    cli("quilt", "--swatch", "studs", "--base", DATA / "penguin/penguin.obj", "--out", out,
        "--elements-only")
    penguin = import_obj("penguin/penguin.obj")
    select(penguin)
    assert bpy.ops.meshmatch.quilt(swatch='studs') == {'FINISHED'}
    q = bpy.data.objects["penguin quilt"]
    want = meshmatch.load(out)
    assert len(q.data.vertices) == want.num_vertices
    ids = np.empty(len(q.data.vertices), np.int32)
    q.data.attributes["element"].data.foreach_get("value", ids)
    assert ids.max() + 1 == len(np.unique(ids)) > 10


def test_curves_make_a_curve_object_with_the_clis_curves(tmp_path, cli):
    out = tmp_path / "c.obj"
    cli("curves", DATA / "cat/cat.obj", "--out", out)
    cat = import_obj("cat/cat.obj")
    select(cat)
    assert bpy.ops.meshmatch.curves() == {'FINISHED'}
    cu = bpy.data.objects["cat curves"]
    n = sum(1 for line in out.read_text().splitlines() if line.startswith("o "))
    assert cu.type == 'CURVE' and len(cu.data.splines) == n > 0


def test_empties_named_as_pairs_become_correspondences():
    from meshmatch_addon import convert, operators

    spot = import_obj("spot/spot.obj")
    penguin = import_obj("penguin/penguin.obj")
    dg = bpy.context.evaluated_depsgraph_get()
    s = convert.extract(spot, dg)
    t = convert.extract(penguin, dg, colors=False, texture=False)
    for name, obj, v in (("Nose.source", spot, 17), ("Nose.target", penguin, 42)):
        e = bpy.data.objects.new(name, None)
        e.location = obj.data.vertices[v].co
        bpy.context.scene.collection.objects.link(e)
    bpy.context.view_layer.update()
    assert operators.pairs_from_empties(s, t) == [(17, 42)]


def test_the_modal_job_reports_progress_and_stops_on_cancel():
    from meshmatch_addon.jobs import Job

    spot = meshmatch.load(DATA / "spot/spot.obj")
    penguin = meshmatch.load(DATA / "penguin/penguin.obj")
    job = Job(meshmatch.transfer, spot, penguin, vertices=200_000).start()
    while job.fraction == 0.0 and not job.done:
        job.wait(0.05)
    job.cancel()
    job.wait()
    assert isinstance(job.error, meshmatch.Cancelled)
    assert job.result is None


def modal_operator(cls, **props):
    """The state `invoke` leaves an operator of `cls` in, on a stand-in object (background mode
    has no window to add a modal handler to): its properties' defaults and `props`, its tasks
    prepared and the first job started. `modal` is then driven with events by hand."""
    import types

    class Stand:
        pass

    op = Stand()
    for k, d in cls.__annotations__.items():
        setattr(op, k, d.keywords.get("default"))
    for k, v in props.items():
        setattr(op, k, v)
    op.reports = []
    op.report = lambda kind, msg: op.reports.append((set(kind), msg))
    for name in ("_prepare", "_next", "_finish", "tasks"):
        setattr(op, name, types.MethodType(getattr(cls, name), op))
    tasks = op._prepare(bpy.context)
    assert tasks
    op._queue, op._done, op._results, op._total, op._timer = list(tasks), 0, [], len(tasks), None
    op._next()
    return op


class Event:
    def __init__(self, kind):
        self.type = kind


def test_the_modal_handler_runs_to_the_end_and_esc_cancels_without_writing():
    cls = bpy.types.MESHMATCH_OT_transfer
    ctx = bpy.context
    spot = import_obj("spot/spot.obj")
    penguin = import_obj("penguin/penguin.obj")
    select(spot, penguin)
    # Esc: the job stops, the handler ends cancelled with a warning, the target is untouched
    op = modal_operator(cls, vertices=200_000)
    while op._job.fraction == 0.0 and not op._job.done:
        assert cls.modal(op, ctx, Event('TIMER')) == {'RUNNING_MODAL'}
        op._job.wait(0.05)
    assert cls.modal(op, ctx, Event('MOUSEMOVE')) == {'PASS_THROUGH'}
    assert cls.modal(op, ctx, Event('ESC')) == {'RUNNING_MODAL'}
    op._job.wait()
    assert cls.modal(op, ctx, Event('TIMER')) == {'CANCELLED'}
    assert op.reports and op.reports[-1][0] == {'WARNING'} and "cancelled" in op.reports[-1][1]
    assert "MeshMatch" not in penguin.data.color_attributes
    # timer events carry it to the end, where the result is written
    op = modal_operator(cls, **FAST)
    while True:
        r = cls.modal(op, ctx, Event('TIMER'))
        if r != {'RUNNING_MODAL'}:
            break
        op._job.wait(0.05)
    assert r == {'FINISHED'}
    assert "MeshMatch" in penguin.data.color_attributes


def test_synthesize_on_a_mesh_without_uvs_or_material_adds_both():
    penguin = import_obj("penguin/penguin.obj")
    assert len(penguin.data.uv_layers) == 0
    img = bpy.data.images.load(str(DATA / "textures" / "5.png"))
    select(penguin)
    assert bpy.ops.meshmatch.synthesize(image=img.name, texture_size=256) == {'FINISHED'}
    assert penguin.data.uv_layers.get("MeshMatch Synth UV") is not None
    result = base_color_image(penguin)
    assert result is not None and tuple(result.size) == (256, 256)
    # The generated atlas's UVs lie in the unit square and the image is not a flat fill.
    layer = penguin.data.uv_layers["MeshMatch Synth UV"]
    uv = np.empty(len(penguin.data.loops) * 2, np.float32)
    layer.uv.foreach_get("vector", uv)
    assert 0.0 <= uv.min() and uv.max() <= 1.0
    assert image_pixels(result).std() > 5


INSTALL = """
import sys, bpy
r = bpy.ops.extensions.package_install_files(
    filepath=sys.argv[-1], repo="user_default", enable_on_install=True)
assert r == {'FINISHED'}, r
assert hasattr(bpy.types, "MESHMATCH_OT_transfer")
assert hasattr(bpy.types, "VIEW3D_PT_meshmatch")
print("installed", bpy.app.version_string)
"""


def test_the_zip_installs_as_an_extension_with_its_wheel(tmp_path):
    out = tmp_path / "ext"
    subprocess.run([sys.executable, str(ROOT / "blender" / "build_extension.py"), "--out",
                    str(out)], check=True, capture_output=True)
    (zp,) = out.glob("meshmatch-*.zip")
    res = tmp_path / "blender"
    r = subprocess.run([sys.executable, "-c", INSTALL, str(zp)], capture_output=True, text=True,
                       env={**os.environ, "BLENDER_USER_RESOURCES": str(res)})
    assert r.returncode == 0, r.stdout + r.stderr
    assert "installed" in r.stdout
    # Blender put the bundled wheel in the extension's own site-packages.
    assert list(res.glob("extensions/.local/lib/python3*/site-packages/meshmatch/_native*.so"))


def test_the_panel_draws_every_operator():
    from types import SimpleNamespace

    class Layout:
        def __init__(self, ops):
            self.ops = ops

        def operator(self, idname, **kw):
            self.ops.append(idname)
            return SimpleNamespace()

        def column(self, **kw):
            return self

        row = box = column

        def prop(self, *a, **kw):
            pass

        prop_search = label = prop

    ops = []
    panel = SimpleNamespace(layout=Layout(ops))
    bpy.types.VIEW3D_PT_meshmatch.draw(panel, bpy.context)
    assert {"meshmatch.transfer", "meshmatch.add_pair", "meshmatch.weather", "meshmatch.complete",
            "meshmatch.curves", "meshmatch.synthesize", "meshmatch.quilt"} <= set(ops)
