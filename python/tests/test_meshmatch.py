"""The Python package on real data: results equal the CLI's on the same input, the shapes and
sizes a caller relies on, progress, cancel, Ctrl-C and refusals."""

import os
import signal
import threading
import time

import numpy as np
import pytest

import meshmatch

# Small working resolutions keep each call to seconds; the CLI runs with the same values.
FAST = dict(vertices=3000, iterations=2)
FAST_FLAGS = ["--vertices", "3000", "--iterations", "2"]


@pytest.fixture(scope="module")
def spot(data):
    return meshmatch.load(data / "spot" / "spot.obj")


@pytest.fixture(scope="module")
def penguin(data):
    return meshmatch.load(data / "penguin" / "penguin.obj")


def ply_colors(path):
    """Per-vertex colours of a PLY written by meshmatch, through the package's own loader."""
    m = meshmatch.load(path)
    assert m.colors is not None
    return m.colors


def test_load_gives_the_files_arrays(spot):
    assert spot.num_vertices == 2930 and spot.num_faces == 5856
    assert spot.vertices.shape == (2930, 3) and spot.vertices.dtype == np.float32
    assert spot.faces.shape == (5856, 3) and spot.faces.max() == 2929
    assert spot.uvs.shape == (3 * 5856, 2)
    assert spot.texture.shape == (1024, 1024, 3) and spot.texture.dtype == np.uint8
    assert spot.colors is None


def test_mesh_from_arrays_round_trips_through_a_file(tmp_path, penguin):
    rng = np.random.default_rng(1)
    cols = rng.random((penguin.num_vertices, 3)).astype(np.float32)
    m = meshmatch.Mesh(penguin.vertices.astype(np.float64), penguin.faces.tolist(), colors=cols)
    m.save(tmp_path / "p.ply")
    back = meshmatch.load(tmp_path / "p.ply")
    np.testing.assert_array_equal(back.vertices, penguin.vertices)
    np.testing.assert_array_equal(back.faces, penguin.faces)
    # PLY stores 8-bit colours.
    assert np.abs(back.colors - cols).max() <= 0.5 / 255 + 1e-6


def test_transfer_colours_equal_the_clis(tmp_path, data, cli, spot, penguin):
    out = tmp_path / "cli.ply"
    cli("transfer", "--source", data / "spot/spot.obj", "--target", data / "penguin/penguin.obj",
        "--out", out, *FAST_FLAGS)
    r = meshmatch.transfer(spot, penguin, **FAST)
    assert r.colors.shape == (penguin.num_vertices, 3)
    assert r.texture is None  # the penguin has no UVs
    assert np.abs(r.colors - ply_colors(out)).max() <= 0.5 / 255 + 1e-6
    # A transfer of Spot's colours, not a flat fill.
    assert r.colors.std(axis=0).min() > 0.05


def scaled_obj(src, dst, s):
    """`src` with every `v` line's coordinates multiplied by `s` in double precision and written
    with all their digits, as a script converting units writes them."""
    lines = []
    for line in src.read_text().splitlines():
        t = line.split()
        if t and t[0] == "v":
            line = "v " + " ".join(repr(float(x) * s) for x in t[1:4])
        lines.append(line)
    dst.write_text("\n".join(lines) + "\n")
    return dst


def test_transfer_is_the_same_in_millimetres(tmp_path, data, spot, penguin):
    # the same pair in metres and in millimetres gives identical colours (docs/formats.md#units)
    for f in ["spot.mtl", "spot_texture.png"]:
        (tmp_path / f).write_bytes((data / "spot" / f).read_bytes())
    spot_mm = meshmatch.load(scaled_obj(data / "spot" / "spot.obj", tmp_path / "spot.obj", 1e3))
    penguin_mm = meshmatch.load(
        scaled_obj(data / "penguin" / "penguin.obj", tmp_path / "penguin.obj", 1e3))
    assert spot_mm.texture is not None
    metres = meshmatch.transfer(spot, penguin, **FAST)
    millimetres = meshmatch.transfer(spot_mm, penguin_mm, **FAST)
    np.testing.assert_array_equal(metres.colors, millimetres.colors)
    # the result keeps the target's own coordinates
    np.testing.assert_array_equal(millimetres.vertices, penguin_mm.vertices)


def test_transfer_to_a_uv_target_bakes_a_texture_of_the_asked_size(spot):
    r = meshmatch.transfer(spot, spot, texture_size=256, **FAST)
    assert r.texture.shape == (256, 256, 3)
    assert r.uvs.shape == spot.uvs.shape
    assert r.colors.shape == (spot.num_vertices, 3)


def test_transfer_takes_pairs_and_refuses_bad_ones(spot, penguin):
    with pytest.raises(meshmatch.MeshMatchError, match="target vertex 99999 out of range"):
        meshmatch.transfer(spot, penguin, [(0, 99999)], **FAST)
    with pytest.raises(meshmatch.MeshMatchError, match="pair 0 is not"):
        meshmatch.transfer(spot, penguin, ["x"], **FAST)


def test_bad_input_raises_the_clis_message(spot, penguin, tmp_path):
    with pytest.raises(meshmatch.MeshMatchError, match=r"--vertices 5: use 128 to"):
        meshmatch.transfer(spot, penguin, vertices=5)
    with pytest.raises(meshmatch.MeshMatchError, match="no texture or vertex colours"):
        meshmatch.transfer(penguin, spot, **FAST)
    with pytest.raises(meshmatch.MeshMatchError, match="face 0 names vertex 7"):
        meshmatch.Mesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 7]])
    with pytest.raises(meshmatch.MeshMatchError, match="not a finite number"):
        meshmatch.transfer(spot, meshmatch.Mesh([[0, 0, np.nan], [1, 0, 0], [0, 1, 0]],
                                                [[0, 1, 2]]), **FAST)
    with pytest.raises(meshmatch.MeshMatchError, match="missing.obj"):
        meshmatch.load(tmp_path / "missing.obj")
    with pytest.raises(meshmatch.MeshMatchError, match="--texture-size 0"):
        meshmatch.bake(spot, spot, texture_size=0)


def test_progress_is_reported_and_an_exception_in_it_stops_the_call(spot, penguin):
    seen = []
    meshmatch.transfer(spot, penguin, progress=lambda f, s: seen.append((f, s)), **FAST)
    assert len(seen) > 3
    assert all(0.0 <= f <= 1.0 for f, _ in seen)
    assert seen[-1][0] > 0.5

    class Stop(Exception):
        pass

    def stop(f, s):
        raise Stop()

    with pytest.raises(Stop):
        meshmatch.transfer(spot, penguin, progress=stop, **FAST)


def test_cancel_stops_a_long_call(spot, penguin):
    token = meshmatch.CancelToken()
    threading.Timer(0.5, token.cancel).start()
    with pytest.raises(meshmatch.Cancelled):
        meshmatch.transfer(spot, penguin, vertices=200_000, cancel=token)
    assert token.cancelled
    with pytest.raises(meshmatch.Cancelled):
        meshmatch.transfer(spot, penguin, cancel=token)


def test_ctrl_c_stops_a_long_call(spot, penguin):
    threading.Timer(0.5, lambda: os.kill(os.getpid(), signal.SIGINT)).start()
    with pytest.raises(KeyboardInterrupt):
        meshmatch.transfer(spot, penguin, vertices=200_000)


def test_the_gil_is_released_while_a_call_runs(spot, penguin):
    done = threading.Event()
    ticks_while_running = []

    def work():
        meshmatch.transfer(spot, penguin, **FAST)
        done.set()

    t = threading.Thread(target=work)
    t.start()
    n = 0
    while not done.is_set():
        n += 1
        time.sleep(0.001)
        if n == 50:
            ticks_while_running.append(n)
    t.join()
    assert ticks_while_running, "the main thread did not run while the transfer ran"


def test_complete_equals_the_clis(tmp_path, data, cli, spot):
    # Synthesise the cow's head (the vertices with the largest z).
    z = spot.vertices[:, 2]
    hole = np.nonzero(z > np.quantile(z, 0.85))[0]
    (tmp_path / "mask.txt").write_text("\n".join(map(str, hole)))
    out = tmp_path / "cli.ply"
    cli("complete", "--mesh", data / "spot/spot.obj", "--mask", tmp_path / "mask.txt",
        "--out", out, *FAST_FLAGS)
    r = meshmatch.complete(spot, hole, textured=False, **FAST)
    assert np.abs(r.colors - ply_colors(out)).max() <= 0.5 / 255 + 1e-6
    flags = np.zeros(spot.num_vertices, bool)
    flags[hole] = True
    r2 = meshmatch.complete(spot, flags, textured=False, **FAST)
    np.testing.assert_array_equal(r.colors, r2.colors)


def test_weather_equals_the_clis(tmp_path, data, cli, spot, penguin):
    out = tmp_path / "cli.ply"
    cli("weather", "--source", data / "spot/spot.obj", "--target", data / "penguin/penguin.obj",
        "--out", out, "--vertices", "4000", "--rays", "16")
    r = meshmatch.weather(spot, penguin, vertices=4000, rays=16)
    assert np.abs(r.colors - ply_colors(out)).max() <= 0.5 / 255 + 1e-6
    out2 = tmp_path / "cli_02.ply"
    cli("weather", "--source", data / "spot/spot.obj", "--target", data / "penguin/penguin.obj",
        "--out", out2, "--vertices", "4000", "--rays", "16", "--components", "0,2")
    r2 = meshmatch.weather(spot, penguin, vertices=4000, rays=16, components=[0, 2])
    assert np.abs(r2.colors - ply_colors(out2)).max() <= 0.5 / 255 + 1e-6
    assert np.abs(r2.colors - r.colors).max() > 0.05, "a component switched off changes nothing"
    with pytest.raises(meshmatch.MeshMatchError, match="no component 7"):
        meshmatch.weather(spot, penguin, vertices=4000, rays=16, components=[7])
    out3 = tmp_path / "cli_affine.ply"
    cli("weather", "--source", data / "spot/spot.obj", "--target", data / "penguin/penguin.obj",
        "--out", out3, "--vertices", "4000", "--rays", "16", "--mean", "affine")
    r3 = meshmatch.weather(spot, penguin, vertices=4000, rays=16, mean="affine")
    assert np.abs(r3.colors - ply_colors(out3)).max() <= 0.5 / 255 + 1e-6
    assert np.abs(r3.colors - r.colors).max() > 0.05, "the paper's affine mean is the default"
    with pytest.raises(meshmatch.MeshMatchError, match="unknown mean"):
        meshmatch.weather(spot, penguin, vertices=4000, rays=16, mean="median")


def test_synthesize_equals_the_clis_texture(tmp_path, data, cli, spot):
    out = tmp_path / "cli.glb"
    ex = data / "textures" / "1.jpg"
    cli("synth", "--exemplar", ex, "--target", data / "spot/spot.obj", "--out", out,
        "--texture-size", "256", "--texel-budget", "20000")
    r = meshmatch.synthesize(str(ex), spot, texture_size=256, texel_budget=20000)
    assert r.texture.shape == (256, 256, 3)
    np.testing.assert_array_equal(r.texture, meshmatch.load(out).texture)


def test_features_equal_the_clis_grey(tmp_path, data, cli, penguin):
    out = tmp_path / "ao.ply"
    cli("features", data / "penguin/penguin.obj", "--out", out, "--rays", "16")
    ao = meshmatch.features(penguin, "ao", rays=16)
    assert ao.shape == (penguin.num_vertices,)
    assert 0.0 <= ao.min() and ao.max() <= 1.0
    assert np.abs(ao - ply_colors(out)[:, 0]).max() <= 0.5 / 255 + 1e-6


def read_png16_grey(path):
    """A 16-bit grey PNG as a float64 array (zlib and the five row filters; no imaging library)."""
    import struct
    import zlib

    raw = path.read_bytes()
    assert raw[:8] == b"\x89PNG\r\n\x1a\n"
    pos, idat, w, h = 8, b"", 0, 0
    while pos < len(raw):
        n, kind = struct.unpack(">I4s", raw[pos:pos + 8])
        body = raw[pos + 8:pos + 8 + n]
        if kind == b"IHDR":
            w, h, depth, colour = struct.unpack(">IIBB", body[:10])
            assert (depth, colour) == (16, 0), (depth, colour)
        elif kind == b"IDAT":
            idat += body
        pos += 12 + n
    data = zlib.decompress(idat)
    bpp, stride = 2, 2 * w
    rows, prev = [], bytearray(stride)
    for y in range(h):
        f = data[y * (stride + 1)]
        line = bytearray(data[y * (stride + 1) + 1:(y + 1) * (stride + 1)])
        for i in range(stride):
            a = line[i - bpp] if i >= bpp else 0
            b = prev[i]
            c = prev[i - bpp] if i >= bpp else 0
            if f == 1:
                line[i] = (line[i] + a) & 255
            elif f == 2:
                line[i] = (line[i] + b) & 255
            elif f == 3:
                line[i] = (line[i] + (a + b) // 2) & 255
            elif f == 4:
                p = a + b - c
                pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                pred = a if pa <= pb and pa <= pc else (b if pb <= pc else c)
                line[i] = (line[i] + pred) & 255
        rows.append(bytes(line))
        prev = line
    return np.frombuffer(b"".join(rows), dtype=">u2").reshape(h, w).astype(np.float64)


def test_feature_maps_equal_the_clis_16_bit_pngs(tmp_path, data, cli, spot):
    out = tmp_path / "spot.png"
    cli("features", data / "spot/spot.obj", "--feature", "ao,normal", "--out", out,
        "--texture-size", "128", "--rays", "16", "--bits", "16")
    maps = meshmatch.feature_maps(spot, "ao,normal", texture_size=128, rays=16)
    assert sorted(maps) == ["ao", "normal"]
    assert maps["ao"].shape == (128, 128) and maps["normal"].shape == (128, 128, 3)
    ao = read_png16_grey(tmp_path / "spot_ao.png") / 65535.0
    assert np.abs(maps["ao"] - ao).max() <= 0.5 / 65535 + 1e-6
    with pytest.raises(meshmatch.MeshMatchError, match="unknown map"):
        meshmatch.feature_maps(spot, "bogus")


def test_curves_are_the_clis(tmp_path, data, cli):
    cat = meshmatch.load(data / "cat" / "cat.obj")
    out = tmp_path / "curves.obj"
    cli("curves", data / "cat/cat.obj", "--out", out)
    cs = meshmatch.curves(cat)
    objs = [l for l in out.read_text().splitlines() if l.startswith("o ")]
    assert len(cs) == len(objs) > 0
    assert [c["kind"] for c in cs] == [o.split("_")[-1] for o in objs]
    assert all(c["points"].shape[1] == 3 for c in cs)


def test_quilt_covers_the_base_with_whole_elements(tmp_path, data, cli, penguin):
    out = tmp_path / "q.ply"
    cli("quilt", "--swatch", "studs", "--base", data / "penguin/penguin.obj", "--out", out,
        "--elements-only")
    elements, ids = meshmatch.quilt(penguin, "studs")
    assert ids.shape == (elements.num_vertices,)
    assert ids.max() + 1 == len(np.unique(ids)) > 10
    np.testing.assert_array_equal(elements.vertices, meshmatch.load(out).vertices)
    # the gap filling only adds elements after the covering pass; off, as `--no-fill`
    unfilled, _ = meshmatch.quilt(penguin, "studs", fill=False)
    assert unfilled.num_vertices <= elements.num_vertices
    cli("quilt", "--swatch", "studs", "--base", data / "penguin/penguin.obj", "--out", out,
        "--elements-only", "--no-fill")
    np.testing.assert_array_equal(unfilled.vertices, meshmatch.load(out).vertices)


def test_bake_gives_a_texture_on_a_generated_atlas(penguin):
    ao = meshmatch.features(penguin, "ao", rays=16)
    grey = penguin.with_colors(np.repeat(ao[:, None], 3, axis=1))
    r = meshmatch.bake(grey, penguin, texture_size=128)
    assert r.texture.shape == (128, 128, 3)
    assert r.uvs.shape == (3 * penguin.num_faces, 2)
    assert r.texture.std() > 5  # the occlusion's shading, not a flat fill


def test_update_and_detail_run_on_edited_meshes(spot, penguin):
    v = spot.vertices.copy()
    moved = v[:, 1] > np.quantile(v[:, 1], 0.9)
    v[moved] *= 1.1
    new = meshmatch.Mesh(v, spot.faces, uvs=spot.uvs)
    r = meshmatch.update(spot, new, textured=False, **FAST)
    assert r.colors.shape == (spot.num_vertices, 3)
    d = meshmatch.detail(spot, penguin, **FAST)
    assert d.num_vertices >= penguin.num_vertices


def test_the_stubs_name_every_function_and_keyword_as_the_module_does():
    import ast
    import inspect
    from pathlib import Path

    stub = ast.parse((Path(meshmatch.__file__).parent / "__init__.pyi").read_text())
    funcs = {f.name: f for f in stub.body if isinstance(f, ast.FunctionDef)}
    for name in ("load", "transfer", "complete", "update", "detail", "synthesize", "weather",
                 "quilt", "curves", "features", "bake"):
        a = funcs[name].args
        in_stub = [x.arg for x in a.posonlyargs + a.args + a.kwonlyargs]
        in_module = list(inspect.signature(getattr(meshmatch, name)).parameters)
        assert in_stub == in_module, name
