"""A USD stage as a spectrack scene dict (docs/usd.md); needs usd-core (``pip install usd-core``).

Mapped: ``Volume`` prims with their ``field:*`` relationships to ``OpenVDBAsset`` prims
(``filePath``, ``fieldName``, ``fieldIndex``): the density field becomes a medium, a
temperature/heat field its blackbody emission, a ``Cd`` field its per-voxel albedo, all read from
the density's file; the ``UsdGeomCamera`` (transform, projection, focal length and apertures);
``UsdLux`` ``DistantLight`` (a directional light), ``DomeLight`` (the environment, uniform or with
its lat-long texture, turned as the dome is: OpenEXR's convention), ``SphereLight`` (a point light of the sphere's intensity, a spot light with
``ShapingAPI``'s cone); the camera's fStop and focusDistance (a thin lens). Everything else that
could shape the image (meshes, other lights, a sphere light's size, the camera's clipping range,
aperture offsets, velocity fields, shears, a dome's tilt off +y or mirror) is named in a warning. The stage's axes and units are kept: coefficients are per stage unit.
"""
import math
import numbers
import os

try:
    from pxr import Gf, Usd, UsdGeom, UsdLux, UsdVol
except ImportError as e:  # pragma: no cover - the message is the point
    raise ImportError("spectrack's USD support needs usd-core: pip install usd-core (" + str(e) + ")") from None

TEMPERATURE_FIELDS = ("temperature", "heat", "flame")
SHAPES = ("Mesh", "Sphere", "Cube", "Cylinder", "Cone", "Capsule", "Points", "BasisCurves", "NurbsPatch")


class _Mapper:
    def __init__(self, stage, time, options):
        self.stage, self.time, self.o = stage, time, options
        self.warnings = []
        self.xf_cache = UsdGeom.XformCache(time)

    def warn(self, prim, what):
        self.warnings.append(f"{self.stage.GetRootLayer().identifier}: {prim.GetPath()}: {what}")

    def error(self, prim, what):
        """A ValueError naming the stage and the prim (and, in `what`, the attribute)."""
        return ValueError(f"{self.stage.GetRootLayer().identifier}: {prim.GetPath()}: {what}")

    def world(self, prim):
        return self.xf_cache.GetLocalToWorldTransform(prim)

    def value(self, attr, default=None):
        v = attr.Get(self.time) if attr and attr.HasAuthoredValue() else None
        return default if v is None else v


def _columns(m):
    """USD matrices act on row vectors: the column-vector linear part A (3x3) and translation."""
    a = [[m[j][i] for j in range(3)] for i in range(3)]
    return a, [m[3][0], m[3][1], m[3][2]]


def matrix_to_transform(m, warn):
    """A spectrack medium transform (scale, then rotations about x, y, z, then translate) of a
    USD matrix; a shear (not representable) is warned about and dropped."""
    a, t = _columns(m)
    scale = [math.sqrt(sum(a[r][c] ** 2 for r in range(3))) for c in range(3)]
    if min(scale) <= 0:
        raise ValueError("a transform with a zero scale")
    r = [[a[i][j] / scale[j] for j in range(3)] for i in range(3)]
    det = (r[0][0] * (r[1][1] * r[2][2] - r[1][2] * r[2][1]) - r[0][1] * (r[1][0] * r[2][2] - r[1][2] * r[2][0])
           + r[0][2] * (r[1][0] * r[2][1] - r[1][1] * r[2][0]))
    if det < 0:  # a mirror: a negative x scale
        scale[0] = -scale[0]
        for i in range(3):
            r[i][0] = -r[i][0]
    off = max(abs(sum(r[k][i] * r[k][j] for k in range(3)) - (i == j)) for i in range(3) for j in range(3))
    if off > 1e-4:
        warn(f"the transform has a shear ({off:.3g}), which spectrack cannot represent: dropped")
    ry = math.asin(max(-1.0, min(1.0, -r[2][0])))
    rx = math.atan2(r[2][1], r[2][2])
    rz = math.atan2(r[1][0], r[0][0])
    return {"scale": scale, "rotate_deg": [math.degrees(v) for v in (rx, ry, rz)], "translate": list(t)}


def _asset_path(mp, prim, attr):
    """The resolved file of an asset attribute: USD's resolver, then the `assets` map (authored
    path -> file), then each folder of `search_paths`."""
    v = mp.value(attr)
    if v is None:
        return None
    authored = v.path
    if authored in mp.o.get("assets", {}):
        return os.path.abspath(mp.o["assets"][authored])
    if v.resolvedPath and os.path.isfile(v.resolvedPath):
        return v.resolvedPath
    for d in mp.o.get("search_paths", ()):
        p = os.path.join(d, os.path.basename(authored))
        if os.path.isfile(p):
            return os.path.abspath(p)
    raise ValueError(f"{mp.stage.GetRootLayer().identifier}: {prim.GetPath()}: {attr.GetName()} @{authored}@ not found "
                     f"next to the stage, in `assets` or in `search_paths`")


def _field(mp, volume, name, path):
    prim = mp.stage.GetPrimAtPath(path)
    if not prim or not prim.IsValid():
        mp.warn(volume, f"field:{name} targets {path}, where the stage has no prim: not mapped")
        return None
    asset = UsdVol.OpenVDBAsset(prim)
    if not asset:
        mp.warn(volume, f"field:{name}: {path} is a {prim.GetTypeName() or 'typeless prim'}, not an OpenVDBAsset: "
                        f"not mapped")
        return None
    file_attr = asset.GetFilePathAttr()
    if mp.value(file_attr) is None:
        samples = file_attr.GetTimeSamples() if file_attr else []
        why = (f"filePath has only time samples ({samples[0]:g} to {samples[-1]:g}) and no default value: give the "
               f"frame (load_usd(..., frame=F), usd2scene --frame F)" if samples
               else "filePath is not set: the OpenVDBAsset names no file")
        if name == "density":
            raise mp.error(prim, why)
        mp.warn(volume, f"field:{name}: {path}: {why}: not mapped")
        return None
    index = mp.value(asset.GetFieldIndexAttr())
    if index is not None and int(index) < 0:
        raise mp.error(prim, f"fieldIndex {index} is negative")
    return {"file": _asset_path(mp, prim, file_attr),
            "name": str(mp.value(asset.GetFieldNameAttr(), "")), "index": index, "prim": prim}


def _material(mp, prim):
    """sigma_s, sigma_a per unit density and the phase: options sigma_t and albedo, a constant
    `albedo` primvar, or the inputs of a bound arnold:standard_volume shader."""
    sigma_t, albedo, g = mp.o.get("sigma_t", 1.0), [mp.o.get("albedo", 0.8)] * 3, 0.0
    shaders = _bound_shaders(mp, prim)
    pv = UsdGeom.PrimvarsAPI(prim).GetPrimvar("albedo")
    if pv and pv.HasAuthoredValue() and not shaders:  # a bound shader gives the albedo
        albedo = _albedo_primvar(mp, prim, pv)
    for shader in shaders:
        get = lambda n, d: mp.value(shader.GetPrim().GetAttribute("inputs:" + n), d)  # noqa: E731
        density = float(get("density", 1.0))
        if not (math.isfinite(density) and density >= 0):
            raise mp.error(shader.GetPrim(), f"inputs:density {density:g} is not a density (a finite value >= 0)")
        sigma_t *= density
        scatter, color = float(get("scatter", 1.0)), list(get("scatter_color", (0.5, 0.5, 0.5)))
        albedo = [min(1.0, max(0.0, scatter * float(c))) for c in color]
        g = float(get("scatter_anisotropy", 0.0))
        if not -1 < g < 1:
            raise mp.error(shader.GetPrim(), f"inputs:scatter_anisotropy {g:g}: the Henyey-Greenstein g is in (-1, 1)")
    sigma_s = [sigma_t * a for a in albedo]
    phase = {"type": "hg", "g": g} if g != 0 else {"type": "isotropic"}
    return sigma_s, [sigma_t - s for s in sigma_s], phase


def _albedo_primvar(mp, prim, pv):
    """A constant `albedo` primvar: one value, or one per channel (a color3f, or an array of one
    color3f as DCCs write constants), each in [0, 1]."""
    if pv.GetInterpolation() != UsdGeom.Tokens.constant:
        raise mp.error(prim, f"primvars:albedo has {pv.GetInterpolation()} interpolation: the import reads a "
                             f"constant albedo")
    value = pv.Get(mp.time)
    if value is None:
        raise mp.error(prim, "primvars:albedo has only time samples and no default value: give the frame "
                             "(load_usd(..., frame=F), usd2scene --frame F)")
    if hasattr(value, "__len__") and len(value) == 1:
        value = value[0]
    try:
        channels = [float(v) for v in value] if hasattr(value, "__len__") else [float(value)] * 3
    except (TypeError, ValueError):
        channels = []
    if len(channels) != 3 or not all(0.0 <= a <= 1.0 for a in channels):
        raise mp.error(prim, f"primvars:albedo {value}: the single-scattering albedo is one value or three (a "
                             f"color3f), each in [0, 1]")
    return channels


def _bound_shaders(mp, prim):
    from pxr import UsdShade
    mat, _ = UsdShade.MaterialBindingAPI(prim).ComputeBoundMaterial()
    if not mat:
        return []
    out = []
    for child in Usd.PrimRange(mat.GetPrim()):
        sh = UsdShade.Shader(child)
        if sh and sh.GetIdAttr().Get() == "arnold:standard_volume":
            out.append(sh)
    return out


def _medium(mp, prim):
    vol = UsdVol.Volume(prim)
    if UsdGeom.Imageable(prim).ComputeVisibility(mp.time) == UsdGeom.Tokens.invisible:
        mp.warn(prim, "invisible (visibility): not rendered")
        return None
    fields = {name: _field(mp, prim, name, path) for name, path in vol.GetFieldPaths().items()}
    fields = {k: v for k, v in fields.items() if v}
    density = fields.pop("density", None)
    if density is None:
        mp.warn(prim, f"no density field (fields: {', '.join(sorted(fields)) or 'none'}): not mapped")
        return None
    sigma_s, sigma_a, phase = _material(mp, prim)
    xf = _field_to_world(mp, prim, density["prim"])
    try:
        transform = matrix_to_transform(xf, lambda w: mp.warn(prim, w))
    except ValueError as e:
        raise mp.error(prim, f"{e} (the volume's and its density field's transforms)") from None
    m = {"name": prim.GetName(), "type": "vdb", "file": density["file"], "grid": density["name"] or "density",
         "sigma_s": sigma_s, "sigma_a": sigma_a, "phase": phase, "transform": transform,
         "_path": str(prim.GetPath())}
    if density["index"] is not None:
        m["grid_index"] = int(density["index"])
    for name, f in fields.items():
        _extra_field(mp, prim, m, name, f)
    return m


def _field_to_world(mp, volume, field):
    """A field's transform is relative to its volume: its world transform when it is the volume's
    descendant, else its own local transform placed in the volume's space."""
    if field.GetPath().HasPrefix(volume.GetPath()):
        return mp.world(field)
    return UsdGeom.Xformable(field).GetLocalTransformation(mp.time) * mp.world(volume)


def _extra_field(mp, prim, m, name, f):
    same_file = f["file"] == m["file"]
    if name.lower() in TEMPERATURE_FIELDS and same_file:
        m["emission"] = {"type": "blackbody", "temperature_grid": f["name"] or name,
                         "temperature_scale": mp.o.get("temperature_scale", 1.0),
                         "normalization": mp.o.get("blackbody_normalization", "peak"),
                         "scale": mp.o.get("emission_scale", 1.0)}
    elif name == "Cd" and same_file:
        m["color"] = {"grid": f["name"] or "Cd", "mode": "albedo"}
    elif name.lower() in ("vel", "velocity", "v"):
        mp.warn(prim, f"field {name}: velocity is not used by the import (for motion blur give the medium "
                      f"\"velocity\": {{\"grid\": \"{f['name'] or name}\"}} and the camera a shutter)")
    else:
        mp.warn(prim, f"field {name} ({f['file']}): not mapped" + ("" if same_file else " (not in the density's file)"))


def _camera(mp, prim, width):
    cam = UsdGeom.Camera(prim)
    gf = cam.GetCamera(mp.time)
    m = mp.world(prim)
    pos = m.Transform(Gf.Vec3d(0, 0, 0))
    forward = m.TransformDir(Gf.Vec3d(0, 0, -1)).GetNormalized()
    up = m.TransformDir(Gf.Vec3d(0, 1, 0))
    h_ap, v_ap = gf.horizontalAperture, gf.verticalAperture
    lens = gf.projection != Gf.Camera.Orthographic or gf.fStop > 0  # an orthographic pinhole needs no focal length
    for attr, v in (("focalLength", gf.focalLength if lens else 1.0), ("horizontalAperture", h_ap),
                    ("verticalAperture", v_ap)):
        if not (math.isfinite(v) and v > 0):
            raise mp.error(prim, f"{attr} {v:g}: a camera needs a finite {attr} > 0")
    height = max(1, round(width * v_ap / h_ap))
    short_ap = min(h_ap, v_ap)
    c = {"position": list(pos), "look_at": list(pos + forward), "up": list(up)}
    if gf.projection == Gf.Camera.Orthographic:
        c.update(type="orthographic", height=short_ap * 0.1)  # apertures in tenths of a stage unit
    else:
        c.update(type="perspective", fov_deg=math.degrees(2 * math.atan(0.5 * short_ap / gf.focalLength)))
    if gf.horizontalApertureOffset or gf.verticalApertureOffset:
        mp.warn(prim, "aperture offsets are not applied (spectrack's frame is centred)")
    if cam.GetClippingRangeAttr().HasAuthoredValue():
        mp.warn(prim, f"clippingRange ({gf.clippingRange.min}, {gf.clippingRange.max}) is not applied "
                      "(rays start at the camera and do not end)")
    if gf.fStop > 0 and gf.focusDistance > 0:
        # a thin lens: the aperture's radius is focalLength / (2 fStop), focalLength in tenths of a unit
        c.update(aperture_radius=0.1 * gf.focalLength / (2.0 * gf.fStop), focus_distance=gf.focusDistance)
    elif gf.fStop > 0:
        mp.warn(prim, f"fStop {gf.fStop} without a focusDistance: no depth of field (a pinhole camera)")
    return c, height


def _intensity(mp, light):
    color = list(mp.value(light.GetColorAttr(), (1.0, 1.0, 1.0)))
    k = float(mp.value(light.GetIntensityAttr(), 1.0)) * 2.0 ** float(mp.value(light.GetExposureAttr(), 0.0))
    return [k * c for c in color], k, color


def _dome_turn(mp, prim, light):
    """The environment's rotate_deg for a dome's lat-long texture: the dome's map follows OpenEXR's
    convention (its centre looks along the dome's +z, u = 0.25 along +x), spectrack's unturned map
    has its centre along -z, and rotate_deg R turns it right-handedly about +y, taking -z to
    (-sin R, 0, -cos R): R is the turn that takes -z to the world direction of the dome's +z (180
    for a dome that is not rotated, 180 + a for rotateY a). A rotation that tilts the pole off +y,
    a mirrored dome and a texture format other than lat-long are warned (read as lat-long, turned
    about +y only)."""
    world = mp.world(prim)
    pole = world.TransformDir(Gf.Vec3d(0, 1, 0)).GetNormalized()
    centre = world.TransformDir(Gf.Vec3d(0, 0, 1))
    if not Gf.IsClose(pole, Gf.Vec3d(0, 1, 0), 1e-6):
        mp.warn(prim, "the dome's rotation tilts its pole off +y; only its turn about +y is applied "
                      "(spectrack's environment map keeps +y up)")
    if world.GetDeterminant3() < 0:
        mp.warn(prim, "the dome is mirrored (a negative scale); its texture is not (spectrack's environment map "
                      "is not mirrored)")
    fmt = mp.value(light.GetTextureFormatAttr(), "automatic")
    if fmt not in ("automatic", "latlong"):
        mp.warn(prim, f"inputs:texture:format {fmt!r}: read as lat-long (spectrack reads lat-long maps only)")
    if math.hypot(centre[0], centre[2]) < 1e-9:  # the centre along the pole: no azimuth to keep
        return 180.0
    turn = math.degrees(math.atan2(-centre[0], -centre[2]))
    return 180.0 if turn == -180.0 else turn


def _light(mp, prim):
    if prim.IsA(UsdLux.DistantLight):
        light = UsdLux.DistantLight(prim)
        irradiance, _, _ = _intensity(mp, light)
        to_light = mp.world(prim).TransformDir(Gf.Vec3d(0, 0, 1))  # the light shines along its -z
        return {"type": "directional", "to_light": list(to_light), "irradiance": irradiance,
                "angle_deg": float(mp.value(light.GetAngleAttr(), 0.0))}
    if prim.IsA(UsdLux.DomeLight):
        light = UsdLux.DomeLight(prim)
        radiance, k, color = _intensity(mp, light)
        tex = light.GetTextureFileAttr()
        if mp.value(tex) is not None and mp.value(tex).path:
            if color != [1.0, 1.0, 1.0]:
                mp.warn(prim, f"inputs:color {color} with a texture: only the intensity scales the map")
            return {"type": "environment", "map": _asset_path(mp, prim, tex), "scale": k,
                    "rotate_deg": _dome_turn(mp, prim, light)}
        return {"type": "environment", "radiance": radiance}
    if prim.IsA(UsdLux.SphereLight):
        return _sphere_light(mp, prim)
    mp.warn(prim, f"{prim.GetTypeName()}: not mapped (spectrack lights: DistantLight, DomeLight, SphereLight)")
    return None


def _sphere_light(mp, prim):
    """A SphereLight as a point light of the same radiant intensity: a sphere of radius r and
    radiance L has I = L pi r^2 (W/sr) from every side; with inputs:normalize the radiance is
    divided by the sphere's area 4 pi r^2 (UsdLux), so I = L / 4. With ShapingAPI's cone it is a
    spot light along the light's -z: cone_angle_deg the cone's angle, cone_delta_deg angle x softness."""
    light = UsdLux.SphereLight(prim)
    radiance, _, _ = _intensity(mp, light)
    m = mp.world(prim)
    r = float(mp.value(light.GetRadiusAttr(), 0.5)) * m.TransformDir(Gf.Vec3d(1, 0, 0)).GetLength()
    normalize = bool(mp.value(light.GetNormalizeAttr(), False))
    area_factor = 0.25 if normalize else math.pi * r * r
    if not normalize and r == 0:
        mp.warn(prim, "SphereLight: radius 0 without inputs:normalize emits nothing")
    elif r > 0:
        mp.warn(prim, f"SphereLight: radius {r:g} rendered as a point light of the same intensity (no soft shadows)")
    light_dict = {"type": "point", "position": list(m.Transform(Gf.Vec3d(0, 0, 0))),
                  "intensity": [area_factor * c for c in radiance]}
    if prim.HasAPI(UsdLux.ShapingAPI):
        shaping = UsdLux.ShapingAPI(prim)
        angle = float(mp.value(shaping.GetShapingConeAngleAttr(), 90.0))
        softness = float(mp.value(shaping.GetShapingConeSoftnessAttr(), 0.0))
        if 0 < angle < 180:
            forward = m.TransformDir(Gf.Vec3d(0, 0, -1)).GetNormalized()
            light_dict.update(type="spot", look_at=list(m.Transform(Gf.Vec3d(0, 0, 0)) + forward),
                              cone_angle_deg=angle, cone_delta_deg=angle * min(max(softness, 0.0), 1.0))
        if mp.value(shaping.GetShapingFocusAttr(), 0.0) or mp.value(shaping.GetShapingIesFileAttr()) is not None:
            mp.warn(prim, "ShapingAPI: focus and IES profiles are not applied")
    return light_dict


# the options stage_to_dict reads besides frame, camera, width and spp (docs/usd.md)
OPTIONS = ("sigma_t", "albedo", "temperature_scale", "emission_scale", "blackbody_normalization", "search_paths",
           "assets")


def _check_options(frame, width, spp, options):
    """The options' types and ranges: TypeError for a wrong type, ValueError naming the option."""
    def number(name, value):
        if isinstance(value, bool) or not isinstance(value, numbers.Real):
            raise TypeError(f"load_usd: {name}={value!r}: a number is needed")
        try:
            as_float = float(value)
        except OverflowError:  # an int beyond a double
            as_float = math.inf
        if not math.isfinite(as_float):
            raise ValueError(f"load_usd: {name}={value!r}: must be finite")
        return as_float
    if frame is not None:
        number("frame", frame)
    for name, value, lo in (("width", width, 1), ("spp", spp, 1)):
        if isinstance(value, bool) or not isinstance(value, numbers.Integral):
            raise TypeError(f"load_usd: {name}={value!r}: a whole number is needed")
        if value < lo:
            raise ValueError(f"load_usd: {name}={value!r}: must be >= {lo}")
    if "albedo" in options and not 0 <= number("albedo", options["albedo"]) <= 1:
        raise ValueError(f"load_usd: albedo={options['albedo']!r}: the single-scattering albedo is in [0, 1]")
    for name in ("sigma_t", "temperature_scale", "emission_scale"):
        if name in options and not number(name, options[name]) >= 0:
            raise ValueError(f"load_usd: {name}={options[name]!r}: must be >= 0")
    folders = options.get("search_paths", ())
    if isinstance(folders, (str, bytes)) or hasattr(folders, "__fspath__") or not hasattr(folders, "__iter__"):
        raise TypeError(f"load_usd: search_paths={folders!r}: a list of folders is needed (search_paths=[folder])")
    folders = options["search_paths"] = list(folders)  # a generator is read once
    for folder in folders:
        if not isinstance(folder, (str, os.PathLike)):
            raise TypeError(f"load_usd: search_paths: {folder!r} is not a folder's path")
    assets = options.get("assets", {})
    if not isinstance(assets, dict):
        raise TypeError(f"load_usd: assets={assets!r}: a dict of authored asset path -> file is needed")
    for authored, file in assets.items():
        if not isinstance(authored, str) or not isinstance(file, (str, os.PathLike)):
            raise TypeError(f"load_usd: assets: {authored!r}: {file!r}: an authored path (str) -> a file's path is "
                            f"needed")


def stage_to_dict(path, frame=None, camera=None, width=512, spp=64, **options):
    """The scene dict of a stage at `frame` (default: the stage's default time) and the warnings.
    options: sigma_t (1, per stage unit), albedo (0.8), temperature_scale (1: the grid in kelvin),
    emission_scale, blackbody_normalization, search_paths (folders for files not found next to
    the stage), assets (authored asset path -> file); any other option is a TypeError."""
    unknown = sorted(set(options) - set(OPTIONS))
    if unknown:
        raise TypeError(f"load_usd: unknown option(s) {', '.join(unknown)} (the options: frame, camera, width, spp, "
                        f"{', '.join(OPTIONS)})")
    _check_options(frame, width, spp, options)
    if os.path.isdir(os.fspath(path)):
        raise IsADirectoryError(f"{path}: is a folder, not a USD stage")
    if not os.path.isfile(os.fspath(path)):
        raise FileNotFoundError(f"{path}: no such USD stage")
    try:
        stage = Usd.Stage.Open(os.fspath(path))
    except Exception as e:  # pxr.Tf.ErrorException: a file USD cannot parse
        raise ValueError(f"{path}: not a USD stage USD can open: {str(e).strip()}") from None
    if stage is None:
        raise ValueError(f"{path}: not a USD stage")
    time = Usd.TimeCode(float(frame)) if frame is not None else Usd.TimeCode.Default()
    mp = _Mapper(stage, time, options)
    media, lights, cams = [], [], []
    for prim in stage.Traverse(Usd.TraverseInstanceProxies()):  # instances' prims too
        if prim.IsA(UsdVol.Volume):
            m = _medium(mp, prim)
            if m:
                media.append(m)
        elif prim.IsA(UsdGeom.Camera):
            cams.append(prim)
        elif prim.HasAPI(UsdLux.LightAPI) or prim.IsA(UsdLux.BoundableLightBase) or prim.IsA(UsdLux.NonboundableLightBase):
            lt = _light(mp, prim)
            if lt:
                lights.append(lt)
        elif prim.GetTypeName() in SHAPES or prim.GetTypeName() == "PointInstancer":
            mp.warn(prim, f"{prim.GetTypeName()}: not mapped (spectrack renders media only)")
    scene = {"format": "spectrack-scene/1", "film": {"width": width, "height": width, "spp": spp},
             "render": {}, "lights": lights, "media": media}
    chosen = stage.GetPrimAtPath(camera) if camera else (cams[0] if cams else None)
    if camera and not (chosen and chosen.IsValid()):
        raise ValueError(f"{path}: camera={camera!r}: no prim at that path (the stage's cameras: "
                         f"{', '.join(str(c.GetPath()) for c in cams) or 'none'})")
    if camera and not chosen.IsA(UsdGeom.Camera):
        raise ValueError(f"{path}: camera={camera!r}: the prim is a {chosen.GetTypeName() or 'typeless prim'}, not a "
                         f"Camera")
    if chosen:
        scene["camera"], scene["film"]["height"] = _camera(mp, chosen, width)
    else:
        scene["camera"] = {"position": "auto"}
        mp.warnings.append(f"{path}: no camera: the default framing of the media")
    if not media:
        raise ValueError(f"{path}: no Volume with a density OpenVDBAsset field" +
                         "".join("\n  " + w for w in mp.warnings))
    _unique_names(media)
    return scene, mp.warnings


def _unique_names(media):
    """A medium's name is its prim's name; where two prims share one (/left/smoke, /right/smoke),
    each of them takes its prim path."""
    counts = {}
    for m in media:
        counts[m["name"]] = counts.get(m["name"], 0) + 1
    for m in media:
        if counts[m["name"]] > 1:
            m["name"] = m.pop("_path")
        else:
            m.pop("_path")
