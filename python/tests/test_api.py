"""The Python module against the command line (same scene and seed: bit-identical arrays), shards
merged in Python, and refused input (ValueError naming the JSON field path, wrong arrays)."""
import itertools
import json
import os
import shutil
import subprocess
import sys

import numpy as np
import pytest

import spectrack
from conftest import ROOT, SHARED

SLAB = {
    "format": "spectrack-scene/1",
    "camera": {"type": "orthographic", "position": [0, 0, -5], "look_at": [0, 0, 0], "up": [0, 1, 0], "height": 3.0},
    "film": {"width": 24, "height": 20, "spp": 4},
    "render": {"seed": 1, "max_depth": 64},
    "lights": [{"type": "environment", "radiance": [1.0, 0.8, 0.6]}],
    "media": [{"name": "slab", "type": "homogeneous", "bounds": [[-1, -1, -0.25], [1, 1, 0.25]],
               "sigma_s": [2.0, 1.0, 0.5], "sigma_a": [0.1, 0.2, 0.4], "phase": {"type": "hg", "g": -0.3}}],
}


def cli_render(binary, scene, out, *flags):
    subprocess.run([binary, "render", str(scene), "-o", str(out), "-q", *flags], check=True)
    return spectrack.read_exr(str(out))


def test_python_equals_cli_bit_for_bit(spectrack_binary, tmp_path):
    scene = ROOT / "docs" / "examples" / "cloud.json"
    flags = ["--spp", "2", "--seed", "5", "--pixel-bounds", "100,140,90,120"]
    cli = cli_render(spectrack_binary, scene, tmp_path / "cli.exr", *flags, "--no-alpha")
    img = spectrack.load_file(scene).render(spp=2, seed=5, pixel_bounds=(100, 140, 90, 120))
    assert img.rgb.dtype == np.float32 and img.rgb.shape == (30, 40, 3)
    assert img.rgb.any()
    for c, name in enumerate("RGB"):
        assert np.array_equal(img.rgb[..., c], cli[name]), name
    # with the alpha layers (the command line's default for an EXR): every channel of the file
    cli_a = cli_render(spectrack_binary, scene, tmp_path / "cli_a.exr", *flags)
    img_a = spectrack.load_file(scene).render(spp=2, seed=5, pixel_bounds=(100, 140, 90, 120), alpha=True)
    assert set(img_a.channels) == set(cli_a) and "A" in cli_a
    for name, plane in img_a.channels.items():
        assert np.array_equal(plane, cli_a[name]), name
    assert img_a.layers["alpha"].shape == (30, 40, 4)
    # and a different seed gives a different image (the comparison can fail)
    other = spectrack.load_file(scene).render(spp=2, seed=6, pixel_bounds=(100, 140, 90, 120))
    assert not np.array_equal(other.rgb, img.rgb)


def test_shards_merge_to_the_single_render(spectrack_binary, tmp_path):
    scene = spectrack.load_dict(SLAB)
    whole = scene.render(spp=6)
    a = scene.render(spp_range=(0, 2))
    b = scene.render(spp_range=(2, 6))
    merged = spectrack.merge([a, b])
    assert merged.spp == 6 and merged.spp_ranges == [(0, 6)]
    with pytest.raises(TypeError, match="merge: 5 is neither"):
        spectrack.merge([a, 5])
    np.testing.assert_allclose(merged.rgb, whole.rgb, rtol=1e-6, atol=0)
    # a shard from the command line merges with one from Python (one render: one scene hash)
    path = tmp_path / "slab.json"
    path.write_text(__import__("json").dumps(SLAB))
    subprocess.run([spectrack_binary, "render", str(path), "-o", str(tmp_path / "b.exr"), "-q", "--spp-range", "2:6",
                    "--no-alpha"], check=True)
    a_file = spectrack.load_file(path).render(spp_range=(0, 2))
    mixed = spectrack.merge([a_file, str(tmp_path / "b.exr")])
    assert mixed.spp == 6
    np.testing.assert_allclose(mixed.rgb, whole.rgb, rtol=1e-6, atol=0)
    with pytest.raises(ValueError, match="overlap"):
        spectrack.merge([a, a])


# A slab lit by a lamp (a medium that emits and does not scatter): guiding="auto" turns guiding on.
LAMP = dict(SLAB, lights=[], media=SLAB["media"] + [
    {"name": "lamp", "type": "homogeneous", "bounds": [[-0.4, 1.2, -1.4], [0.4, 1.8, -0.8]],
     "sigma_s": [0, 0, 0], "sigma_a": [20, 20, 20], "emission": {"radiance": [8, 8, 8]}}])


def test_guiding_and_a_shared_guide_cache(tmp_path):
    scene = spectrack.load_dict(LAMP)
    assert scene.render(spp=6, guiding="auto").stats["guiding_used"]
    assert not scene.render(spp=6, guiding="off").stats["guiding_used"]
    assert not spectrack.load_dict(SLAB).render(spp=6).stats["guiding_used"], "auto: no lamp, no guiding"
    whole = scene.render(spp=10)
    cache = tmp_path / "guide.cache"
    a = scene.render(spp_range=(0, 6), guide_cache=cache)
    b = scene.render(spp_range=(6, 10), guide_cache=str(cache))
    assert (a.stats["guide_cache_file"], b.stats["guide_cache_file"]) == ("written", "read")
    assert b.stats["guide_training_passes"] == 0
    np.testing.assert_allclose(spectrack.merge([a, b]).rgb, whole.rgb, rtol=1e-5, atol=1e-7)
    unguided = scene.render(spp=10, guiding="off")
    assert not np.allclose(unguided.rgb, whole.rgb, rtol=1e-5, atol=1e-7), "the comparison sees the guide"
    with pytest.raises(ValueError, match="guide_cache"):
        scene.render(spp=6, guiding="off", guide_cache=cache)
    with pytest.raises(ValueError, match="guiding=sometimes"):
        scene.render(spp=6, guiding="sometimes")
    assert whole.stats["guide_splitting"] == "off", "auto guides directions alone"
    assert scene.render(spp=6, guide_splitting=True).stats["guide_splitting"] == "on"
    assert scene.render(spp=6, guiding="on", guide_splitting=False).stats["guide_splitting"] == "off"
    with pytest.raises(ValueError, match="guide_splitting=True"):
        scene.render(spp=6, guiding="off", guide_splitting=True)


def test_write_and_read_back(tmp_path):
    img = spectrack.load_dict(SLAB).render(spp=2, aovs=["variance"])
    img.write(str(tmp_path / "x.exr"))
    back = spectrack.read(str(tmp_path / "x.exr"))
    assert back.spp == 2 and "variance" in img.layers
    with pytest.raises(ValueError, match='compression="lzw": unknown'):
        img.write(str(tmp_path / "y.exr"), compression="lzw")
    assert not (tmp_path / "y.exr").exists()
    img.write(str(tmp_path / "y.exr"), compression="piz")
    np.testing.assert_array_equal(back.rgb, img.rgb)
    assert img.stats["spp"] == 2 and img.stats["tracker"] == "spectral-decomposition" and img.stats["paths"] > 0


def test_a_piece_written_so_that_merge_refuses_it_warns(tmp_path, recwarn):
    """As the command line warns before a piece renders: merge refuses lossy or half pieces."""
    scene = spectrack.load_dict(SLAB)
    piece = scene.render(spp_range=(0, 2))
    for name, kwargs in [("dwaa", {"compression": "dwaa"}), ("pxr24", {"compression": "pxr24"}),
                         ("half", {"half": True})]:
        with pytest.warns(UserWarning, match="merge refuses it"):
            piece.write(str(tmp_path / f"{name}.exr"), **kwargs)
    tile = scene.render(spp=2, pixel_bounds=(0, 12, 0, 20))
    with pytest.warns(UserWarning, match="compressed with dwab"):
        tile.write(str(tmp_path / "tile.exr"), compression="dwab")
    # a piece read back is still a piece where its samples or window show it (a shard from sample 0
    # reads as a whole render of fewer samples); a whole render, or a lossless piece, writes silently
    scene.render(spp_range=(2, 4)).write(str(tmp_path / "zip.exr"))
    back = spectrack.read(str(tmp_path / "zip.exr"))
    with pytest.warns(UserWarning, match="stored as half floats"):
        back.write(str(tmp_path / "back.exr"), half=True)
    recwarn.clear()
    scene.render(spp=2).write(str(tmp_path / "whole.exr"), compression="dwaa")
    piece.write(str(tmp_path / "piz.exr"), compression="piz")
    piece.write(str(tmp_path / "piece.png"))
    assert not [w for w in recwarn if issubclass(w.category, UserWarning)]


def test_what_the_command_line_refuses_is_refused(spectrack_binary, tmp_path):
    # a noise target on a tile or a shard (each would stop at its own noise), on several devices
    target = spectrack.load_dict(dict(SLAB, render=dict(SLAB["render"], noise_target=0.2, adaptive=True),
                                      film=dict(SLAB["film"], spp=32)))
    with pytest.raises(ValueError, match="with --spp-range or --pixel-bounds"):
        target.render(pixel_bounds=(0, 12, 0, 10))
    with pytest.raises(ValueError, match="with --spp-range or --pixel-bounds"):
        target.render(spp_range=(0, 16))
    with pytest.raises(ValueError, match="several devices"):
        target.render(device="0:0,0:0")
    # an adaptive render written from Python is refused by both merges, as the command line's
    adaptive = target.render()
    assert "samples" in adaptive.channels
    adaptive.write(str(tmp_path / "ad.exr"))
    with pytest.raises(ValueError, match="an adaptive render cannot be merged"):
        spectrack.merge([adaptive])
    merged = subprocess.run([spectrack_binary, "merge", str(tmp_path / "m.exr"), str(tmp_path / "ad.exr")],
                            capture_output=True, text=True)
    assert merged.returncode == 2 and "an adaptive render cannot be merged" in merged.stderr, merged.stderr
    # read back, it is the same image with its samples per pixel, and merge still refuses it
    back = spectrack.read(str(tmp_path / "ad.exr"))
    assert sorted(back.channels) == sorted(adaptive.channels)
    for name, values in adaptive.channels.items():
        np.testing.assert_array_equal(back.channels[name], values, err_msg=name)
    np.testing.assert_array_equal(back.rgb, adaptive.rgb)
    assert back.stats["adaptive_mean_spp"] == pytest.approx(float(np.mean(adaptive.channels["samples"])))
    with pytest.raises(ValueError, match="an adaptive render cannot be merged"):
        spectrack.merge([back])
    with pytest.raises(ValueError, match="an adaptive render cannot be merged"):
        spectrack.merge([str(tmp_path / "ad.exr")])
    back.write(str(tmp_path / "ad2.exr"))
    again = spectrack.read_exr(str(tmp_path / "ad2.exr"))
    for name, values in spectrack.read_exr(str(tmp_path / "ad.exr")).items():
        np.testing.assert_array_equal(again[name], values, err_msg=name)
    # a scheme the tracker ignores, chunks of samples with one device
    with pytest.raises(ValueError, match="ignores the spectral scheme"):
        spectrack.load_dict(SLAB).render(tracker="delta", scheme="average")
    with pytest.raises(ValueError, match="this render has one device"):
        spectrack.load_dict(SLAB).render(chunk_spp=2)
    # the twins: what is allowed still renders
    assert spectrack.load_dict(SLAB).render(tracker="spectral", scheme="average", spp=1).spp == 1
    assert spectrack.load_dict(SLAB).render(spp_range=(0, 2)).spp == 2


def test_bad_field_names_its_path():
    bad = {**SLAB, "media": [{**SLAB["media"][0], "sigma_s": [2.0, -1.0, 0.5]}]}
    with pytest.raises(ValueError, match=r"<dict>: /media/0/sigma_s"):
        spectrack.load_dict(bad)
    with pytest.raises(ValueError, match=r"/film/width"):
        spectrack.load_dict({**SLAB, "film": {**SLAB["film"], "width": "wide"}})
    with pytest.raises(ValueError, match=r"/render/tracker"):
        spectrack.load_file(ROOT / "docs" / "examples" / "ortho_slab.json", render={"tracker": "nope"})
    with pytest.raises(ValueError, match="tracker=nope"):
        spectrack.load_dict(SLAB).render(tracker="nope")


def test_overrides_merge_into_the_file():
    s = spectrack.load_file(ROOT / "docs" / "examples" / "ortho_slab.json", film={"width": 8, "height": 6, "spp": 1})
    assert (s.width, s.height, s.spp) == (8, 6, 1)
    assert s.render().rgb.shape == (6, 8, 3)


def test_overrides_read_the_file_as_the_loader_does(tmp_path):
    """With overrides the file is read after the loader's checks of it, so a USD stage is named as
    one (with the converter) and a FIFO is refused, as without overrides; text that is not JSON says so."""
    stage = tmp_path / "stage.usda"
    stage.write_text("#usda 1.0\n")
    for overrides in ({}, {"film": {"spp": 1}}):
        with pytest.raises(ValueError, match="is a USD stage.*usd2scene"):
            spectrack.load_file(stage, **overrides)
    fifo = tmp_path / "pipe.json"
    os.mkfifo(fifo)
    with pytest.raises(ValueError, match="FIFO"):
        spectrack.load_file(fifo, film={"spp": 1})
    (tmp_path / "bad.json").write_bytes(b"{\xff")
    with pytest.raises(ValueError, match="bad.json: not JSON"):
        spectrack.load_file(tmp_path / "bad.json", film={"spp": 1})


def test_a_scene_dict_names_the_same_files_from_any_folder(tmp_path, monkeypatch):
    """scene.dict's paths are absolute (a file's relative paths resolved against its folder), so a
    scene rebuilt from it in another folder reads the same files, never a namesake there; its
    Volumes are kept (a copy shares them and keeps them alive); each call gives a new dict."""
    import copy
    import gc
    s = spectrack.load_file(ROOT / "data" / "scenes" / "cloud.json", film={"width": 8, "height": 6, "spp": 1})
    assert s.dict["media"][0]["file"] == str(ROOT / "data" / "volumes" / "cloud.vdb")
    other = tmp_path / "a" / "b"
    other.mkdir(parents=True)
    (tmp_path / "a" / "volumes").mkdir()
    d = np.zeros((4, 4, 4), dtype=np.float32)
    d[1:3, 1:3, 1:3] = 1
    namesake = spectrack.Volume.from_numpy(d, voxel_size=0.5)
    shutil.copy(namesake.file, tmp_path / "a" / "volumes" / "cloud.vdb")  # ../volumes from a/b
    monkeypatch.chdir(other)
    np.testing.assert_array_equal(spectrack.load_dict(s.dict).render(seed=3).rgb, s.render(seed=3).rgb)
    # the twin: the file's own relative path, resolved here, is the namesake, another image
    relative = json.loads((ROOT / "data" / "scenes" / "cloud.json").read_text())
    relative["film"] = {"width": 8, "height": 6, "spp": 1}
    assert relative["media"][0]["file"] == "../volumes/cloud.vdb"
    assert not np.array_equal(spectrack.load_dict(relative).render(seed=3).rgb, s.render(seed=3).rgb)
    s.dict["film"]["spp"] = 7
    assert s.dict["film"]["spp"] == 1 and s.dict is not s.dict
    as_tuple = spectrack.load_dict({**s.dict, "media": (relative["media"][0],)}, base_dir=ROOT / "data" / "scenes")
    assert as_tuple.dict["media"][0]["file"] == str(ROOT / "data" / "volumes" / "cloud.vdb")  # a tuple section too
    import pathlib
    as_path = {**relative, "media": [{**relative["media"][0], "file": pathlib.Path(ROOT / "data" / "volumes" / "cloud.vdb")}]}
    np.testing.assert_array_equal(spectrack.load_dict(as_path).render(seed=3).rgb, s.render(seed=3).rgb)
    v = spectrack.Volume.from_numpy(d, voxel_size=0.5)
    made = spectrack.load_dict({**SLAB, "media": [{"type": "vdb", "file": v, "sigma_s": [1, 1, 1], "sigma_a": [0, 0, 0]}]})
    again = copy.deepcopy(made.dict)
    assert again["media"][0]["file"] is v
    del made, v
    gc.collect()
    assert spectrack.load_dict(again).render(spp=1).rgb.shape[2] == 3  # the Volume's file is still there


def test_wrong_arrays_are_refused():
    with pytest.raises(TypeError, match="dtype int64"):
        spectrack.Volume.from_numpy(np.ones((4, 4, 4), dtype=np.int64))
    with pytest.raises(TypeError, match="dtype"):
        spectrack.Volume.from_numpy(np.ones((4, 4, 4), dtype=np.complex64))
    with pytest.raises(ValueError, match="2 dimensions"):
        spectrack.Volume.from_numpy(np.ones((4, 4), dtype=np.float32))
    with pytest.raises(ValueError, match=r"density\[1, 2, 3\] = -1"):
        d = np.zeros((4, 4, 4), dtype=np.float32)
        d[1, 2, 3] = -1
        spectrack.Volume.from_numpy(d)
    with pytest.raises(ValueError, match="finite"):
        spectrack.Volume.from_numpy(np.full((2, 2, 2), np.nan, dtype=np.float32))
    with pytest.raises(ValueError, match="voxel_size"):
        spectrack.Volume.from_numpy(np.ones((2, 2, 2), dtype=np.float32), voxel_size=0)


def test_arguments_a_user_passes_from_numpy_and_pathlib(tmp_path):
    import pathlib
    cube = np.ones((2, 2, 2), dtype=np.float32)
    # the transform OpenVDB takes and the float coordinates: refused by name, not a RuntimeError
    with pytest.raises(ValueError, match="voxel_size 1e-20 is outside"):
        spectrack.Volume.from_numpy(cube, voxel_size=1e-20)
    with pytest.raises(ValueError, match="origin x = 1e"):
        spectrack.Volume.from_numpy(cube, origin=(1e30, 0, 0))
    with pytest.raises(ValueError, match="float32's range"):
        spectrack.Volume.from_numpy(np.full((2, 2, 2), 1e39))
    with pytest.raises(ValueError, match="grid must not be empty"):
        spectrack.Volume.from_numpy(cube, grid="")
    # numpy scalars are JSON numbers; a NaN is named by its path
    scene = spectrack.load_dict({**SLAB, "camera": {**SLAB["camera"], "height": np.float32(3)}})
    assert scene.width == SLAB["film"]["width"]
    with pytest.raises(ValueError, match=r"<dict>: /film/spp: nan"):
        spectrack.load_dict({**SLAB, "film": {**SLAB["film"], "spp": float("nan")}})
    # aovs: one name, "alpha" among them; and what the command line refuses
    s = spectrack.load_dict(SLAB)
    assert "depth" in s.render(spp=1, aovs="depth").layers
    assert "alpha" in s.render(spp=1, aovs=["alpha"]).layers
    with pytest.raises(ValueError, match="alpha=False"):
        s.render(spp=1, aovs=["alpha"], alpha=False)
    with pytest.raises(ValueError, match="chunk_spp=-1"):
        s.render(spp=2, chunk_spp=-1, device="0:0,0:0")
    # paths: pathlib everywhere, any iterable for merge
    img = s.render(spp=2)
    img.write(pathlib.Path(tmp_path) / "p.exr")
    back = spectrack.read(pathlib.Path(tmp_path) / "p.exr")
    assert back.spp == 2 and "R" in spectrack.read_exr(pathlib.Path(tmp_path) / "p.exr")
    assert spectrack.merge((img,)).spp == 2
    # a half-float file is read for its channels (merge still refuses it)
    img.write(str(tmp_path / "h.exr"), half=True)
    np.testing.assert_allclose(spectrack.read_exr(str(tmp_path / "h.exr"))["R"], img.channels["R"], rtol=1e-3, atol=1e-3)
    with pytest.raises(ValueError, match="32-bit float"):
        spectrack.read(str(tmp_path / "h.exr"))


def test_progress_exceptions_carry_the_image_and_nothing_empty_is_written(tmp_path):
    s = spectrack.load_dict(SLAB)
    def at_the_end(f):
        if f >= 1.0:
            raise RuntimeError("stop")
    with pytest.raises(RuntimeError) as e:
        s.render(spp=2, progress=at_the_end)
    assert e.value.image.spp == 2 and not e.value.image.interrupted
    def at_once(f):
        raise RuntimeError("stop")
    with pytest.raises(RuntimeError) as e:
        s.render(spp=2, progress=at_once)
    img = e.value.image
    if img.interrupted:  # stopped before the render's end (else the last call raised): a stop from outside, as Ctrl-C
        assert img.stats["stop_reason"] == "signal"
    if img.spp == 0:  # stopped before the first batch: nothing to write, as the command line
        with pytest.raises(ValueError, match="no finished sample"):
            img.write(str(tmp_path / "z.exr"))
    else:
        img.write(str(tmp_path / "z.exr"))
        assert spectrack.read(str(tmp_path / "z.exr")).spp == img.spp


def test_sparse_volume_and_devices():
    d = np.zeros((8, 8, 8), dtype=np.float32)
    d[2:4, 2:5, 3] = 0.5
    v = spectrack.Volume.from_numpy(d, voxel_size=0.1, origin=(1, 2, 3))
    assert v.active_voxels == 6 and v.shape == [8, 8, 8]
    devs = spectrack.devices()
    assert devs and {"spec", "name", "type"} <= set(devs[0])


def test_without_usd_core_the_rest_works(tmp_path):
    code = ("import sys; sys.modules['pxr'] = None\n"
            "import spectrack\n"
            "assert spectrack.load_dict({'format': 'spectrack-scene/1', 'film': {'width': 2, 'height': 2, 'spp': 1}})"
            ".render().spp == 1\n"
            "try:\n    spectrack.load_usd('x.usda')\nexcept ImportError as e:\n    print(e)\n")
    env = {**os.environ, "PYTHONPATH": os.path.dirname(os.path.dirname(spectrack.__file__))}
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=tmp_path, env=env)
    assert r.returncode == 0, r.stderr
    assert "pip install usd-core" in r.stdout


def test_volume_from_file_is_the_file(tmp_path):
    cloud = str(ROOT / "data" / "volumes" / "cloud.vdb")
    base = {**SLAB, "media": [{"type": "vdb", "file": cloud, "density_scale": 4, "sigma_s": [1, 1, 1],
                               "sigma_a": [0.1, 0.1, 0.1]}], "camera": {"look_at": "media", "fit": 1.1}}
    by_path = spectrack.load_dict(base).render(spp=1)
    vol = spectrack.Volume.from_file(cloud)
    by_volume = spectrack.load_dict({**base, "media": [{**base["media"][0], "file": vol}]}).render(spp=1)
    np.testing.assert_array_equal(by_volume.rgb, by_path.rgb)
    assert by_path.rgb.max() > 0
    assert vol.active_voxels > 0 and min(vol.shape) > 0
    with pytest.raises(ValueError, match="no such volume file"):
        spectrack.Volume.from_file(str(ROOT / "missing.vdb"))
    # the file is read when the Volume is made: a missing grid, a file that is not a VDB, a truncated one
    with pytest.raises(ValueError, match="no grid 'smoke'.*'density'"):
        spectrack.Volume.from_file(cloud, grid="smoke")
    not_vdb = tmp_path / "not.vdb"
    not_vdb.write_bytes(b"P6\n4 4\n255\n" + bytes(48))
    with pytest.raises(ValueError, match="not.vdb"):
        spectrack.Volume.from_file(str(not_vdb))
    cut = tmp_path / "cut.vdb"
    cut.write_bytes(open(cloud, "rb").read()[:1000])
    with pytest.raises(ValueError, match="cut.vdb"):
        spectrack.Volume.from_file(str(cut))


def test_stats_and_metadata_are_the_command_lines(spectrack_binary, tmp_path):
    """Image.stats of a noise-target or adaptive render holds the keys --stats-json writes (one
    render_metadata), and a scene's own time limit stops a Python render as it stops the CLI's."""
    path = ROOT / "docs" / "examples" / "cloud.json"
    overrides = {"film": {"width": 16, "height": 12, "spp": 64}, "render": {"noise_target": 0.3, "adaptive": True}}
    im = spectrack.load_file(path, **overrides).render()
    scene = tmp_path / "cloud.json"
    doc = json.loads(path.read_text())
    for k, v in overrides.items():
        doc[k] = {**doc.get(k, {}), **v}
    for m in doc["media"]:  # the file beside the example, from the copy's folder
        m["file"] = str((path.parent / m["file"]).resolve())
    scene.write_text(json.dumps(doc))
    subprocess.run([spectrack_binary, "render", str(scene), "-o", str(tmp_path / "c.exr"), "-q", "--stats-json",
                    str(tmp_path / "s.json")], check=True)
    cli = json.loads((tmp_path / "s.json").read_text())
    for key in ("noise_target", "noise_error", "noise_pixels", "adaptive_rounds", "adaptive_floor",
                "adaptive_mean_spp", "stop_reason"):
        assert key in cli and key in im.stats, key
        assert im.stats[key] == pytest.approx(cli[key]), key
    # the scene's render.time_limit, not only the argument (it was ignored in Python)
    slow = spectrack.load_dict({**SLAB, "film": {"width": 64, "height": 64, "spp": 1 << 22},
                                "render": {**SLAB["render"], "time_limit": 2.0}})
    try:
        t = slow.render()
    except TimeoutError as e:  # a machine so loaded that no sample finished: the limit held all the same
        assert "the time limit of 2 s came before any sample finished" in str(e)
    else:
        assert t.interrupted and t.stats["stop_reason"] == "time-limit" and t.stats["time_limit"] == 2.0


def test_arguments_of_the_wrong_type_are_named(tmp_path):
    s = spectrack.load_dict(SLAB)
    for kwargs, words in [({"spp": 2.5}, "spp must be an int"), ({"spp": True}, "spp must be an int"),
                          ({"seed": "1"}, "seed must be an int"), ({"guiding": True}, "guiding must be a str"),
                          ({"alpha": "yes"}, "alpha must be True or False"), ({"time_limit": "x"}, "time_limit must be a number"),
                          ({"spp_range": (0,)}, "spp_range must be 2 ints"), ({"pixel_bounds": []}, "pixel_bounds must be 4 ints"),
                          ({"aovs": 3}, "aovs must be a layer name"), ({"progress": 3}, "progress must be callable")]:
        with pytest.raises(TypeError, match=words):
            s.render(**kwargs)
    with pytest.raises(ValueError, match="spp=1099511627776 is out of range"):
        s.render(spp=1 << 40)
    im = s.render(spp=np.int64(2), device=None, chunk_spp=None, verbose=np.False_)  # numpy ints and bools; None: the default
    assert im.spp == 2
    # the other functions name the argument too (pybind11's own message lists the signature)
    d = np.ones((2, 2, 2), dtype=np.float32)
    for call, words in [(lambda: spectrack.Volume.from_numpy(d, voxel_size=(1, 2, 3)), "voxel_size must be a number"),
                        (lambda: spectrack.Volume.from_numpy(d, voxel_size=True), "voxel_size must be a number"),
                        (lambda: spectrack.Volume.from_numpy(d, origin="abc"), "origin must be 3 numbers"),
                        (lambda: spectrack.Volume.from_numpy(d, origin=(1, 2)), "origin must be 3 numbers"),
                        (lambda: spectrack.Volume.from_numpy(d, grid=3), "grid must be a str"),
                        (lambda: spectrack.Volume.from_numpy("abc"), "dtype"),
                        (lambda: spectrack.Volume.from_file(ROOT / "data" / "volumes" / "cloud.vdb", grid=None),
                         "grid must be a str"),
                        (lambda: im.write(tmp_path / "x.exr", half="yes"), "half must be True or False"),
                        (lambda: im.write(tmp_path / "x.exr", compression=3), "compression must be a str"),
                        (lambda: spectrack.merge(3), "a list of images or paths is needed, not 3"),
                        (lambda: spectrack.Volume.from_numpy(d, origin={1.0, 2.0, 3.0}), "origin must be 3 numbers"),
                        (lambda: spectrack.Volume.from_numpy(d, origin=itertools.count()), "origin must be 3 numbers"),
                        (lambda: spectrack.Volume.from_numpy(d, origin=list(range(1000))), r"\.\.\.\)$"),
                        (lambda: spectrack.Volume.from_numpy(d, voxel_size=1j), "voxel_size must be a number")]:
        with pytest.raises(TypeError, match=words):
            call()
    with pytest.raises(ValueError, match="voxel_size = 1000000000000"):
        spectrack.Volume.from_numpy(d, voxel_size=10**400)
    # what they take: numpy scalars and arrays, nested lists, numpy's bool
    v = spectrack.Volume.from_numpy([[[1.0, 2.0]]], voxel_size=np.float32(0.5), origin=np.array([1.0, 2.0, 3.0]))
    assert list(v.shape) == [1, 1, 2]
    import decimal
    assert spectrack.Volume.from_numpy(d, voxel_size=np.array(0.5), origin=(decimal.Decimal(1), 2, 3)).shape == [2, 2, 2]
    im.write(tmp_path / "h.exr", half=np.True_)
    assert spectrack.merge(x for x in [im]).spp == 2


def test_messages_and_file_names_that_are_not_utf8(tmp_path):
    # a damaged header's attribute name (bytes from the file) stays in the message
    bad = tmp_path / "g.exr"
    bad.write_bytes(bytes.fromhex("762f3101c6bbebf3b00000000000000022007cf9000000000000a40000000000c80000000000000000"))
    with pytest.raises(ValueError, match=r"damaged OpenEXR header: attribute '\\xa4'"):
        spectrack.read_exr(str(bad))
    # a file name that is not UTF-8 (as os.fsdecode gives it) loads, renders, writes and reads
    name = os.fsdecode(os.fsencode(str(tmp_path)) + b"/\xff.json")
    with open(os.fsencode(name), "w") as f:
        json.dump(SLAB, f)
    img = spectrack.load_file(name, film={"spp": 2}).render()
    out = os.fsdecode(os.fsencode(str(tmp_path)) + b"/\xfe.exr")
    img.write(out)
    assert spectrack.read(out).spp == 2 and spectrack.load_file(name).width == 24
    with pytest.raises(ValueError, match=r"\\xfd_missing.json: cannot open"):
        spectrack.load_file(os.fsdecode(os.fsencode(str(tmp_path)) + b"/\xfd_missing.json"))


def test_scene_warnings_reach_sys_stderr():
    """A notebook shows sys.stderr, not the process's stderr: the scene's warnings go there."""
    import contextlib
    import io
    d = {**SLAB, "media": [{**SLAB["media"][0], "majorant_scale": 0.75}]}
    buf = io.StringIO()
    with contextlib.redirect_stderr(buf):
        spectrack.load_dict(d).render(spp=1)
    assert "/media/0/majorant_scale: 0.75 < 1 under-estimates the majorant" in buf.getvalue()


def test_png_options_and_read_refusals(tmp_path):
    img = spectrack.load_dict(SLAB).render(spp=2)
    with pytest.raises(ValueError, match="half=True: the output .*a PNG"):
        img.write(str(tmp_path / "a.png"), half=True)
    with pytest.raises(ValueError, match="compression: the output .*a PNG"):
        img.write(str(tmp_path / "a.png"), compression="dwaa")
    img.write(str(tmp_path / "a.png"))
    with pytest.raises(ValueError, match="a png image, not an EXR"):
        spectrack.read_exr(str(tmp_path / "a.png"))
    img.write(str(tmp_path / "h.exr"), half=True)
    with pytest.raises(ValueError, match="read: .*half.*read_exr reads any"):
        spectrack.read(str(tmp_path / "h.exr"))
    assert spectrack.read_exr(str(tmp_path / "h.exr"))["R"].shape == (20, 24)


def test_volumes_of_other_precisions_and_the_unnamed_grid():
    with pytest.raises(ValueError, match=r"voxel_size 1e-06 is outside \[1.5e-05, 1e12\]"):
        spectrack.Volume.from_numpy(np.ones((2, 2, 2), np.float32), voxel_size=1e-6)
    assert spectrack.Volume.from_numpy(np.ones((2, 2, 2), np.float16), voxel_size=2e-5).shape == [2, 2, 2]
    blosc = SHARED / "smoke1-blosc.nvdb"  # its only float grid has no name: a medium's "density" renders it
    if blosc.exists():
        assert spectrack.Volume.from_file(str(blosc)).active_voxels > 0
    sphere = SHARED / "levelset" / "sphere.vdb"
    if sphere.exists():
        with pytest.raises(ValueError, match="cannot be a density: a level set"):
            spectrack.Volume.from_file(str(sphere), grid="ls_sphere")
