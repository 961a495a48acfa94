"""USD in: the real stages of ../shared/data/vdb (OpenUSD's and Arnold's test scenes) load with
their volumes, camera and lights, and render; what is not mapped is named in a warning. Skipped,
with the reason, when usd-core is not installed (scripts/test.sh installs it when it can)."""
import math
import subprocess
import sys
import warnings

import numpy as np
import pytest

pytest.importorskip("pxr", reason="usd-core is not installed (pip install usd-core): the USD tests need it")

import spectrack  # noqa: E402
from spectrack.usd import stage_to_dict  # noqa: E402
from conftest import SHARED  # noqa: E402

USD = SHARED / "usd"
ARNOLD = SHARED / "arnold-usd"


def test_openusd_vdb_volume_stage():
    scene, warns = stage_to_dict(USD / "refs" / "vdbVolume.usda", search_paths=[str(USD)], width=64, spp=2)
    (m,) = scene["media"]
    assert m["file"].endswith("smoke_000002.vdb") and m["grid"] == "density"
    assert m["transform"]["translate"] == pytest.approx([0, -4, 0])
    assert m["transform"]["rotate_deg"] == pytest.approx([-90, 0, 0], abs=1e-9)
    assert m["sigma_s"] == pytest.approx([0.2] * 3)  # the stage's constant albedo primvar
    (sun,) = scene["lights"]
    assert sun["type"] == "directional" and sun["to_light"] == pytest.approx([-1, 0, 0], abs=1e-9)
    assert sun["irradiance"] == pytest.approx([16, 0, 0])  # color (1, 0, 0), exposure 4
    cam = scene["camera"]
    assert cam["position"] == pytest.approx([0, 0, 110]) and cam["look_at"] == pytest.approx([0, 0, 109])
    assert cam["fov_deg"] == pytest.approx(math.degrees(2 * math.atan(0.5 * 15.2908 / 150)), rel=1e-5)
    assert scene["film"]["height"] == round(64 * 15.2908 / 20.955)
    assert any("Checkerboard: Mesh: not mapped" in w for w in warns)
    # focalLength 150 (tenths of a unit), fStop 100: a lens of radius 15 / 200 units, in focus at 200
    assert cam["aperture_radius"] == pytest.approx(0.075) and cam["focus_distance"] == pytest.approx(200.0)
    with warnings.catch_warnings(record=True):
        warnings.simplefilter("always")
        img = spectrack.load_usd(USD / "refs" / "vdbVolume.usda", search_paths=[str(USD)], width=64, spp=2).render()
    assert img.rgb.shape == (47, 64, 3) and img.rgb[..., 0].max() > 0 and img.rgb[..., 1].max() == 0


def test_time_samples_pick_the_frame():
    stage = USD / "refs" / "vdbVolumeFallbackMaterial.usda"
    files = {f: stage_to_dict(stage, frame=f, search_paths=[str(USD)])[0]["media"][0]["file"] for f in (1, 3)}
    assert files[1] != files[3]


def test_arnold_grids_by_index_with_dome_and_houdini_camera():
    scene, warns = stage_to_dict(ARNOLD / "refs" / "test_2315" / "test.usda", search_paths=[str(ARNOLD)], width=48)
    assert sorted(m["grid_index"] for m in scene["media"]) == [0, 1, 2]
    assert {m["name"]: m["transform"]["translate"][2] for m in scene["media"]} == pytest.approx(
        {"volume_0": 0, "volume_1": 1, "volume_2": 2})
    assert scene["lights"] == [{"type": "environment", "radiance": [1.0, 1.0, 1.0]}]
    assert scene["camera"]["type"] == "perspective" and any("clippingRange" in w for w in warns)
    with warnings.catch_warnings(record=True):
        warnings.simplefilter("always")
        img = spectrack.load_usd(ARNOLD / "refs" / "test_2315" / "test.usda", search_paths=[str(ARNOLD)], width=48,
                                 spp=2).render()
    assert 0 < img.rgb.mean() < 1


def test_instancer_is_named_and_assets_map_files():
    stage = ARNOLD / "refs" / "test_0030" / "scene.usda"
    with pytest.raises(ValueError, match="smoke.vdb@ not found"):
        stage_to_dict(stage)
    scene, warns = stage_to_dict(stage, assets={"./smoke.vdb": str(SHARED / "smoke1.vdb")})
    assert scene["media"][0]["file"].endswith("smoke1.vdb")
    assert any("PointInstancer: not mapped" in w for w in warns) and any("no camera" in w for w in warns)


def test_usd2scene_writes_a_scene_the_cli_renders(spectrack_binary, tmp_path):
    out = tmp_path / "scene.json"
    r = subprocess.run([sys.executable, "-m", "spectrack.usd2scene", str(USD / "refs" / "vdbVolume.usda"), "-o", str(out),
                        "--search-path", str(USD), "--width", "32", "--spp", "1"], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert "warning:" in r.stderr and "Mesh: not mapped" in r.stderr
    subprocess.run([spectrack_binary, "render", str(out), "-o", str(tmp_path / "x.exr"), "-q"], check=True)
    assert np.asarray(spectrack.read_exr(str(tmp_path / "x.exr"))["R"]).max() > 0
    # every option of load_usd is a flag; a folder that does not exist is an error, not a traceback
    r = subprocess.run([sys.executable, "-m", "spectrack.usd2scene", str(USD / "refs" / "vdbVolume.usda"), "-o",
                        str(tmp_path / "flags.json"), "--search-path", str(USD), "--emission-scale", "2",
                        "--blackbody-normalization", "none", "--asset", "no/such.vdb=" + str(USD / "smoke1.vdb")],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    r = subprocess.run([sys.executable, "-m", "spectrack.usd2scene", str(USD / "refs" / "vdbVolume.usda"), "-o",
                        str(tmp_path / "none" / "s.json"), "--search-path", str(USD)], capture_output=True, text=True)
    assert r.returncode == 1 and "cannot write the scene" in r.stderr and "Traceback" not in r.stderr, r.stderr
    with pytest.raises(TypeError, match="unknown option.*albdo"):
        spectrack.load_usd(USD / "refs" / "vdbVolume.usda", search_paths=[str(USD)], albdo=0.5)


def test_a_made_stage_maps_fields_dome_texture_and_warns_by_name(tmp_path):
    from pxr import Gf, Sdf, Usd, UsdGeom, UsdLux, UsdVol
    env = tmp_path / "sky.png"
    spectrack.load_dict({"format": "spectrack-scene/1", "film": {"width": 8, "height": 4, "spp": 1},
                         "lights": [{"type": "environment", "radiance": [0.2, 0.4, 0.8]}]}).render().write(str(env))
    stage = Usd.Stage.CreateNew(str(tmp_path / "made.usda"))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
    vol = UsdVol.Volume.Define(stage, "/fire")
    vol.AddTranslateOp().Set(Gf.Vec3d(1, 2, 3))
    vol.AddScaleOp().Set(Gf.Vec3f(2, 2, 2))
    for name, field in (("density", "density"), ("temperature", "heat"), ("vel", "v")):
        asset = UsdVol.OpenVDBAsset.Define(stage, f"/fire/{name}")
        asset.CreateFilePathAttr().Set(Sdf.AssetPath(str(USD / "densityAndHeat.vdb")))
        asset.CreateFieldNameAttr().Set(field)
        vol.CreateFieldRelationship(name, asset.GetPath())
    dome = UsdLux.DomeLight.Define(stage, "/sky")
    dome.CreateTextureFileAttr().Set(Sdf.AssetPath(str(env)))
    dome.CreateIntensityAttr().Set(0.5)
    dome.CreateExposureAttr().Set(1.0)
    sun = UsdLux.DistantLight.Define(stage, "/sun")
    sun.CreateAngleAttr().Set(0.53)
    sun.AddRotateXOp().Set(-90.0)  # its +z turned to +y: it shines along -y
    bulb = UsdLux.SphereLight.Define(stage, "/bulb")
    bulb.CreateRadiusAttr().Set(0.5)
    bulb.CreateIntensityAttr().Set(4.0)
    bulb.AddTranslateOp().Set(Gf.Vec3d(0, 0, 20))
    lamp = UsdLux.SphereLight.Define(stage, "/lamp")
    lamp.CreateNormalizeAttr().Set(True)
    lamp.CreateIntensityAttr().Set(8.0)
    shaping = UsdLux.ShapingAPI.Apply(lamp.GetPrim())
    shaping.CreateShapingConeAngleAttr().Set(30.0)
    shaping.CreateShapingConeSoftnessAttr().Set(0.5)
    cam = UsdGeom.Camera.Define(stage, "/cam")
    cam.AddTranslateOp().Set(Gf.Vec3d(0, -30, 5))
    cam.AddRotateXOp().Set(90.0)  # looking along +y, up +z
    cam.CreateFocalLengthAttr().Set(50.0)
    cam.CreateFStopAttr().Set(2.5)
    cam.CreateFocusDistanceAttr().Set(30.0)
    stage.GetRootLayer().Save()

    scene, warns = stage_to_dict(tmp_path / "made.usda", width=32, temperature_scale=2600)
    (m,) = scene["media"]
    assert m["transform"]["scale"] == pytest.approx([2, 2, 2]) and m["transform"]["translate"] == pytest.approx([1, 2, 3])
    assert m["emission"]["temperature_grid"] == "heat" and m["emission"]["temperature_scale"] == 2600
    by_type = {lt["type"]: lt for lt in scene["lights"]}
    dome_l, sun_l = by_type["environment"], by_type["directional"]
    # a sphere of radius r and radiance L: I = L pi r^2; normalized: I = L / 4, a spot along -z
    assert by_type["point"]["position"] == pytest.approx([0, 0, 20])
    assert by_type["point"]["intensity"] == pytest.approx([4.0 * math.pi * 0.25] * 3)
    assert by_type["spot"]["intensity"] == pytest.approx([2.0] * 3)
    assert by_type["spot"]["look_at"] == pytest.approx([0, 0, -1], abs=1e-9)
    assert by_type["spot"]["cone_angle_deg"] == 30.0 and by_type["spot"]["cone_delta_deg"] == 15.0
    assert scene["camera"]["aperture_radius"] == pytest.approx(0.1 * 50.0 / (2 * 2.5))
    assert scene["camera"]["focus_distance"] == pytest.approx(30.0)
    # OpenEXR's lat-long convention (the map's centre along +z): spectrack's map turned by 180 degrees
    assert dome_l == {"type": "environment", "map": str(env), "scale": pytest.approx(1.0), "rotate_deg": 180.0}
    assert sun_l["to_light"] == pytest.approx([0, 1, 0], abs=1e-9)
    assert sun_l["angle_deg"] == pytest.approx(0.53)
    assert scene["camera"]["look_at"] == pytest.approx([0, -29, 5], abs=1e-9)
    assert scene["camera"]["up"] == pytest.approx([0, 0, 1], abs=1e-9)
    assert any("/bulb: SphereLight: radius 0.5 rendered as a point light" in w for w in warns)
    assert any("/fire: field vel: velocity is not used" in w for w in warns)
    with warnings.catch_warnings(record=True):
        warnings.simplefilter("always")
        img = spectrack.load_usd(tmp_path / "made.usda", width=32, spp=1, temperature_scale=2600).render()
    assert img.rgb.max() > 0


def test_a_turned_dome_turns_its_map(tmp_path):
    """A dome turned about +y turns the map by as much, right-handed as both turn (rotateY a: 180 +
    a); a dome tilted off +y keeps its turn about +y, a mirrored dome and a texture format that is
    not lat-long are warned."""
    from pxr import Gf, Sdf, Usd, UsdLux, UsdVol
    env = tmp_path / "sky.png"
    spectrack.load_dict({"format": "spectrack-scene/1", "film": {"width": 8, "height": 4, "spp": 1},
                         "lights": [{"type": "environment", "radiance": [0.2, 0.4, 0.8]}]}).render().write(str(env))
    turns = {}
    for name, ops in (("plain", ()), ("y90", (("Y", 90.0),)), ("y-135", (("Y", -135.0),)),
                      ("tilted", (("Y", 90.0), ("X", 30.0))), ("mirrored", (("S", -1.0),)), ("angular", ())):
        stage = Usd.Stage.CreateInMemory()
        vol = UsdVol.Volume.Define(stage, "/smoke")
        asset = UsdVol.OpenVDBAsset.Define(stage, "/smoke/density")
        asset.CreateFilePathAttr().Set(Sdf.AssetPath(str(USD / "densityAndHeat.vdb")))
        asset.CreateFieldNameAttr().Set("density")
        vol.CreateFieldRelationship("density", asset.GetPath())
        dome = UsdLux.DomeLight.Define(stage, "/sky")
        dome.CreateTextureFileAttr().Set(Sdf.AssetPath(str(env)))
        for axis, angle in ops:
            if axis == "S":
                dome.AddScaleOp().Set(Gf.Vec3f(angle, 1.0, 1.0))
            else:
                getattr(dome, f"AddRotate{axis}Op")().Set(angle)
        if name == "angular":
            dome.CreateTextureFormatAttr().Set("angular")
        path = tmp_path / f"{name}.usda"
        stage.GetRootLayer().Export(str(path))
        scene, warns = stage_to_dict(path, width=8)
        (light,) = scene["lights"]
        turns[name] = light["rotate_deg"]
        assert any("tilts its pole" in w for w in warns) == (name == "tilted"), (name, warns)
        assert any("mirrored" in w for w in warns) == (name == "mirrored"), (name, warns)
        assert any("'angular': read as lat-long" in w for w in warns) == (name == "angular"), (name, warns)
    assert turns["plain"] == pytest.approx(180.0) and turns["angular"] == pytest.approx(180.0)
    assert turns["y90"] == pytest.approx(-90.0)  # 180 + 90: the dome's +z along +x, where R = -90 takes -z
    assert turns["y-135"] == pytest.approx(45.0)  # 180 - 135
    assert turns["tilted"] == pytest.approx(-90.0)


def test_options_and_paths_are_checked_by_name():
    stage = USD / "refs" / "vdbVolume.usda"
    with pytest.raises(FileNotFoundError, match="no such USD stage"):
        stage_to_dict(USD / "nope.usda")
    with pytest.raises(ValueError, match="camera='/nope': no prim"):
        stage_to_dict(stage, camera="/nope", search_paths=[str(USD)])
    with pytest.raises(ValueError, match="not a Camera"):
        stage_to_dict(stage, camera="/Lights/Left", search_paths=[str(USD)])
    with pytest.raises(TypeError, match="frame='abc'"):
        stage_to_dict(stage, frame="abc", search_paths=[str(USD)])
    with pytest.raises(ValueError, match="frame=nan"):
        stage_to_dict(stage, frame=float("nan"), search_paths=[str(USD)])
    with pytest.raises(ValueError, match="albedo=2"):
        stage_to_dict(stage, albedo=2, search_paths=[str(USD)])
    with pytest.raises(ValueError, match="frame=1000.*must be finite"):
        stage_to_dict(stage, frame=10**400, search_paths=[str(USD)])
    with pytest.raises(TypeError, match="search_paths: 5 is not a folder's path"):
        stage_to_dict(stage, search_paths=[5])
    with pytest.raises(TypeError, match="assets: 'a.vdb': 5"):
        stage_to_dict(stage, assets={"a.vdb": 5}, search_paths=[str(USD)])
    with pytest.raises(IsADirectoryError, match="is a folder, not a USD stage"):
        stage_to_dict(USD)
    with pytest.raises(ValueError, match="vdbVolume.usda: .*not found"):
        stage_to_dict(stage)  # the file it names is one folder up: not found without search_paths
    scene, _ = stage_to_dict(stage, camera="/main_cam", search_paths=[str(USD)], width=16, spp=1)  # the twin
    assert scene["camera"]["type"] == "perspective"


def _smoke_stage(tmp_path, name, edit):
    """A stage of one Volume /vol with a density field on smoke_000002.vdb and a camera; `edit(stage)`
    changes one thing before it is saved."""
    from pxr import Gf, Sdf, Usd, UsdGeom, UsdVol
    stage = Usd.Stage.CreateNew(str(tmp_path / name))
    cam = UsdGeom.Camera.Define(stage, "/cam")
    cam.AddTranslateOp().Set(Gf.Vec3d(0, 0, 60))
    vol = UsdVol.Volume.Define(stage, "/vol")
    asset = UsdVol.OpenVDBAsset.Define(stage, "/vol/density")
    asset.CreateFilePathAttr().Set(Sdf.AssetPath(str(USD / "smoke_000002.vdb")))
    asset.CreateFieldNameAttr().Set("density")
    vol.CreateFieldRelationship("density", asset.GetPath())
    edit(stage)
    stage.GetRootLayer().Save()
    return tmp_path / name


def test_everyday_stages_map_and_damaged_ones_are_named(tmp_path):
    """Volumes of one name under two parents, volumes of instances, a colour albedo, a dangling
    field, an invisible volume; and a time-sampled or missing filePath, a zero scale, a camera of
    focal length 0, an albedo or shader density out of range: each refusal names the prim and field."""
    from pxr import Gf, Sdf, Usd, UsdGeom, UsdShade, UsdVol

    def copy_vol(stage, path):
        stage.DefinePrim(path.rsplit("/", 1)[0], "Xform")
        Sdf.CopySpec(stage.GetRootLayer(), "/vol", stage.GetRootLayer(), path)
        UsdVol.Volume(stage.GetPrimAtPath(path)).CreateFieldRelationship("density", Sdf.Path(path + "/density"))

    def two_parents(stage):
        copy_vol(stage, "/left/smoke")
        copy_vol(stage, "/right/smoke")
        stage.RemovePrim("/vol")

    scene, _ = stage_to_dict(_smoke_stage(tmp_path, "two.usda", two_parents), width=8, spp=1)
    assert sorted(m["name"] for m in scene["media"]) == ["/left/smoke", "/right/smoke"]

    def instanced(stage):
        copy_vol(stage, "/proto/vol")
        for p, inst in (("/a", True), ("/b", False)):
            prim = stage.DefinePrim(p, "Xform")
            prim.GetReferences().AddInternalReference("/proto")
            prim.SetInstanceable(inst)
        stage.RemovePrim("/vol")
        stage.GetPrimAtPath("/proto").SetSpecifier(Sdf.SpecifierClass)

    scene, _ = stage_to_dict(_smoke_stage(tmp_path, "inst.usda", instanced), width=8, spp=1)
    assert sorted(m["name"] for m in scene["media"]) == ["/a/vol", "/b/vol"]  # the instance's volume too

    def colour(stage):
        UsdGeom.PrimvarsAPI(stage.GetPrimAtPath("/vol")).CreatePrimvar(
            "albedo", Sdf.ValueTypeNames.Color3f).Set(Gf.Vec3f(0.5, 0.6, 0.7))
        UsdVol.Volume(stage.GetPrimAtPath("/vol")).CreateFieldRelationship("heat", "/vol/nowhere")

    scene, warns = stage_to_dict(_smoke_stage(tmp_path, "colour.usda", colour), width=8, spp=1)
    (m,) = scene["media"]
    assert m["sigma_s"] == pytest.approx([0.5, 0.6, 0.7]) and m["sigma_a"] == pytest.approx([0.5, 0.4, 0.3])
    assert any("/vol: field:heat targets /vol/nowhere, where the stage has no prim" in w for w in warns)

    def hidden(stage):
        UsdGeom.Imageable(stage.GetPrimAtPath("/vol")).MakeInvisible()

    with pytest.raises(ValueError, match=r"no Volume with a density[\s\S]*/vol: invisible"):
        stage_to_dict(_smoke_stage(tmp_path, "hidden.usda", hidden), width=8, spp=1)

    def sampled(stage):
        attr = stage.GetPrimAtPath("/vol/density").GetAttribute("filePath")
        attr.Clear()
        for t in (1, 2, 3):
            attr.Set(Sdf.AssetPath(str(USD / f"smoke_00000{t}.vdb")), Usd.TimeCode(t))

    stage = _smoke_stage(tmp_path, "sampled.usda", sampled)
    with pytest.raises(ValueError, match=r"/vol/density: filePath has only time samples \(1 to 3\).*frame="):
        stage_to_dict(stage, width=8, spp=1)
    assert stage_to_dict(stage, frame=3, width=8, spp=1)[0]["media"][0]["file"].endswith("smoke_000003.vdb")  # twin

    refusals = [
        ("nofile.usda", lambda s: s.GetPrimAtPath("/vol/density").GetAttribute("filePath").Clear(),
         "/vol/density: filePath is not set"),
        ("flat.usda", lambda s: UsdGeom.Xformable(s.GetPrimAtPath("/vol")).AddScaleOp().Set(Gf.Vec3f(0, 1, 1)),
         "/vol: a transform with a zero scale"),
        ("focal.usda", lambda s: UsdGeom.Camera(s.GetPrimAtPath("/cam")).CreateFocalLengthAttr().Set(0.0),
         "/cam: focalLength 0: a camera needs"),
        ("albedo.usda", lambda s: UsdGeom.PrimvarsAPI(s.GetPrimAtPath("/vol")).CreatePrimvar(
            "albedo", Sdf.ValueTypeNames.Float).Set(3.0), "/vol: primvars:albedo 3"),
        ("index.usda", lambda s: UsdVol.OpenVDBAsset(s.GetPrimAtPath("/vol/density")).CreateFieldIndexAttr().Set(-1),
         "/vol/density: fieldIndex -1 is negative"),
    ]
    for name, edit, message in refusals:
        with pytest.raises(ValueError, match=message.replace("(", r"\(")):
            stage_to_dict(_smoke_stage(tmp_path, name, edit), width=8, spp=1)

    def dense_shader(stage):
        mat = UsdShade.Material.Define(stage, "/mat")
        sh = UsdShade.Shader.Define(stage, "/mat/vol")
        sh.CreateIdAttr().Set("arnold:standard_volume")
        sh.CreateInput("density", Sdf.ValueTypeNames.Float).Set(-2.0)
        UsdShade.MaterialBindingAPI.Apply(stage.GetPrimAtPath("/vol")).Bind(mat)

    with pytest.raises(ValueError, match="/mat/vol: inputs:density -2 is not a density"):
        stage_to_dict(_smoke_stage(tmp_path, "shader.usda", dense_shader), width=8, spp=1)

    def ortho_no_focal(stage):  # an orthographic pinhole has no use for a focal length
        cam = UsdGeom.Camera(stage.GetPrimAtPath("/cam"))
        cam.CreateProjectionAttr().Set(UsdGeom.Tokens.orthographic)
        cam.CreateFocalLengthAttr().Set(0.0)

    scene, _ = stage_to_dict(_smoke_stage(tmp_path, "ortho.usda", ortho_no_focal), width=8, spp=1)
    assert scene["camera"]["type"] == "orthographic"

    def side_fields(stage):  # a field other than density without a file is warned, not fatal
        asset = UsdVol.OpenVDBAsset.Define(stage, "/vol/vel")
        UsdVol.Volume(stage.GetPrimAtPath("/vol")).CreateFieldRelationship("vel", asset.GetPath())
        pv = UsdGeom.PrimvarsAPI(stage.GetPrimAtPath("/vol")).CreatePrimvar("albedo", Sdf.ValueTypeNames.Color3fArray)
        pv.Set([Gf.Vec3f(0.2, 0.4, 0.6)])  # a constant written as an array of one, as DCCs do

    scene, warns = stage_to_dict(_smoke_stage(tmp_path, "side.usda", side_fields), width=8, spp=1)
    assert scene["media"][0]["sigma_s"] == pytest.approx([0.2, 0.4, 0.6])
    assert any("/vol: field:vel: /vol/vel: filePath is not set" in w for w in warns)

    def varying(stage):
        pv = UsdGeom.PrimvarsAPI(stage.GetPrimAtPath("/vol")).CreatePrimvar(
            "albedo", Sdf.ValueTypeNames.FloatArray, UsdGeom.Tokens.vertex)
        pv.Set([0.5, 0.5, 0.5])

    with pytest.raises(ValueError, match="/vol: primvars:albedo has vertex interpolation"):
        stage_to_dict(_smoke_stage(tmp_path, "varying.usda", varying), width=8, spp=1)

    def forward_g(stage):
        dense_shader(stage)
        sh = UsdShade.Shader(stage.GetPrimAtPath("/mat/vol"))
        sh.GetInput("density").Set(1.0)
        sh.CreateInput("scatter_anisotropy", Sdf.ValueTypeNames.Float).Set(1.5)

    with pytest.raises(ValueError, match=r"/mat/vol: inputs:scatter_anisotropy 1.5: the Henyey-Greenstein g is in \(-1, 1\)"):
        stage_to_dict(_smoke_stage(tmp_path, "forward.usda", forward_g), width=8, spp=1)


def test_usd2scene_writes_nothing_that_render_refuses(tmp_path):
    """A stage that maps to a scene spectrack refuses (a light of negative intensity) is an error of
    usd2scene, and no scene file is left; the same stage with a positive intensity converts."""
    from pxr import UsdLux

    def sun(intensity):
        return lambda stage: UsdLux.DistantLight.Define(stage, "/sun").CreateIntensityAttr().Set(intensity)

    for intensity, code in ((-2.0, 1), (2.0, 0)):
        stage = _smoke_stage(tmp_path, f"sun{code}.usda", sun(intensity))
        out = tmp_path / f"sun{code}.json"
        p = subprocess.run([sys.executable, "-m", "spectrack.usd2scene", str(stage), "-o", str(out)],
                           capture_output=True, text=True)
        assert p.returncode == code, p.stderr
        assert out.exists() == (code == 0)
        if code:
            assert "the stage maps to a scene spectrack refuses" in p.stderr and "/lights/0/irradiance" in p.stderr
