"""spectrack from Python: load or build a scene, render it, get numpy arrays (docs/python.md).

The renderer, the scene loader and its validation, and the film pieces are the library of the
``spectrack`` command (the extension module ``spectrack._spectrack``); this file only turns
Python values into scene JSON. A scene dict is the scene file's JSON as Python values, where a
medium's ``file`` may also be a :class:`Volume`. Errors in a scene raise ``ValueError`` whose
message names the file (``<dict>`` for a dict), the JSON field path and the reason.
"""
import copy
import json
import numbers
import os

from ._spectrack import Image, Volume, devices, merge, read, read_exr  # noqa: F401
from . import _spectrack

__all__ = ["Scene", "Image", "Volume", "load_file", "load_dict", "load_usd", "merge", "read", "read_exr",
           "devices", "__version__"]
__version__ = _spectrack.__version__


class Scene:
    """A validated scene; ``render`` renders it (the keyword arguments override the scene's values)."""

    def __init__(self, desc, volumes=(), scene_dict=None, json_text="", base_dir=None):
        self._desc = desc
        self._text = json_text  # what a scene made in memory was parsed from: its identity for merging
        self._volumes = list(volumes)  # kept alive: their files are the media's files
        self._dict = scene_dict  # the scene JSON as a dict, its Volumes kept (None for a file loaded as it is)
        self._base_dir = base_dir  # the folder its relative paths resolved against

    @property
    def dict(self):
        """The scene's JSON as a new dict (None for a file loaded as it is): its Volumes kept, and its
        paths (film.output, lights' map, media's file) absolute, so that load_dict of it, from any
        folder, names the files this scene read."""
        if self._dict is None:
            return None
        d = copy.deepcopy(self._dict)
        _absolute_paths(d, self._base_dir)
        return d

    @dict.setter
    def dict(self, value):  # what .dict gives back; the scene itself is what it was loaded as
        self._dict = copy.deepcopy(value)

    path = property(lambda self: self._desc.path)
    width = property(lambda self: self._desc.width)
    height = property(lambda self: self._desc.height)
    spp = property(lambda self: self._desc.spp)
    seed = property(lambda self: self._desc.seed)

    def render(self, spp=None, seed=None, device="", spp_range=None, pixel_bounds=None, tracker=None, scheme=None,
               guiding=None, guide_cache=None, alpha=None, aovs=(), time_limit=None, chunk_spp=0, progress=None,
               verbose=False, guide_splitting=None):
        """Renders the scene and returns an :class:`Image`.

        spp: samples per pixel (film.spp); seed: render.seed; device: "P:D", a name substring, "all"
        or a comma-separated list ("" the default device); spp_range: (begin, end), samples
        begin..end-1 of every pixel (a shard, for merge); pixel_bounds: (x0, x1, y0, y1);
        tracker, scheme: names as `spectrack render` takes them; guiding: "off", "on" or "auto"
        (render.guiding); guide_cache: a file path, the trained guide cache that shards, tiles and
        later renders share (written by the first render that names it, read by the others);
        guide_splitting: True or False, guided roulette and splitting (--guide-splitting; default:
        on with guiding="on", off where auto guides; True without guiding raises ValueError);
        alpha: the alpha layers (default: film.alpha, else off, so .rgb is the whole beauty); aovs:
        film layer names; time_limit: seconds;
        progress: called with the fraction done, on the calling thread. The GIL is released while the
        devices render. Ctrl-C stops the render at its next iteration and raises KeyboardInterrupt
        with the finished samples' image as its ``image`` attribute.
        """
        _check_render_args(spp=spp, seed=seed, device=device, spp_range=spp_range, pixel_bounds=pixel_bounds,
                           tracker=tracker, scheme=scheme, guiding=guiding, alpha=alpha, aovs=aovs,
                           time_limit=time_limit, chunk_spp=chunk_spp, progress=progress, verbose=verbose,
                           guide_splitting=guide_splitting)
        device = "" if device is None else device  # None: the default, as for the other arguments
        chunk_spp = 0 if chunk_spp is None else chunk_spp
        return _spectrack.render(self._desc, spp=spp, seed=seed, device=device, spp_range=spp_range,
                                 pixel_bounds=pixel_bounds, tracker=tracker, scheme=scheme, guiding=guiding,
                                 guide_cache=os.fspath(guide_cache) if guide_cache is not None else "", alpha=alpha,
                                 aovs=[aovs] if isinstance(aovs, str) else list(aovs), time_limit=time_limit, chunk_spp=chunk_spp, verbose=verbose,
                                 progress=progress, json_text=self._text, guide_splitting=guide_splitting)

    def __repr__(self):
        return f"<spectrack.Scene {self.path} {self.width}x{self.height}, {self.spp} spp>"


# The Python types of render's arguments (None: the scene's value), checked before the extension
# module sees them, so that a TypeError names the argument; the values are the module's checks.
_INT, _REAL, _STR, _BOOL = "an int", "a number", "a str", "True or False"
_RENDER_ARG_TYPES = {"spp": _INT, "seed": _INT, "chunk_spp": _INT, "time_limit": _REAL, "device": _STR,
                     "tracker": _STR, "scheme": _STR, "guiding": _STR, "alpha": _BOOL, "verbose": _BOOL,
                     "guide_splitting": _BOOL}


def _is_bool(value):  # Python's bool, or numpy's (numpy.bool_, named numpy.bool since numpy 2)
    return isinstance(value, bool) or (type(value).__module__ == "numpy" and type(value).__name__ in ("bool", "bool_"))


def _is(value, kind):
    if kind == _BOOL:
        return _is_bool(value)
    if kind == _STR:
        return isinstance(value, str)
    if _is_bool(value):
        return False  # True is no sample count
    if kind == _INT:
        return isinstance(value, numbers.Integral)
    return isinstance(value, numbers.Real)


# the integers the module's arguments hold (int32 or int64): beyond them no value is in range
_INT_BOUND = {"spp": 2**31, "chunk_spp": 2**31, "seed": 2**63, "spp_range": 2**63, "pixel_bounds": 2**31}


def _check_render_args(**args):
    def bounded(name, value):
        if not -_INT_BOUND[name] <= value < _INT_BOUND[name]:
            raise ValueError(f"render: {name}={value!r} is out of range")

    for name, kind in _RENDER_ARG_TYPES.items():
        value = args[name]
        if value is not None and not _is(value, kind):
            raise TypeError(f"render: {name} must be {kind}, not {type(value).__name__} ({value!r})")
        if value is not None and name in _INT_BOUND:
            bounded(name, value)
    for name, count in (("spp_range", 2), ("pixel_bounds", 4)):
        value = args[name]
        if value is None:
            continue
        try:
            items = list(value)
        except TypeError:
            items = None
        if items is None or len(items) != count or not all(_is(v, _INT) for v in items):
            raise TypeError(f"render: {name} must be {count} ints, not {value!r}")
        for v in items:
            bounded(name, v)
    aovs = args["aovs"]
    try:
        names = isinstance(aovs, str) or all(isinstance(a, str) for a in aovs)
    except TypeError:  # not iterable
        names = False
    if not names:
        raise TypeError(f"render: aovs must be a layer name or a list of them, not {aovs!r}")
    if args["progress"] is not None and not callable(args["progress"]):
        raise TypeError(f"render: progress must be callable (it is called with the fraction done), "
                        f"not {args['progress']!r}")


def _with_volumes(value, volumes):
    """The scene dict as JSON values: each Volume in a medium's "file" becomes its file (and "grid"
    its grid, unless the medium names one); the Volumes are collected into `volumes`."""
    if isinstance(value, dict):
        out = {}
        for k, v in value.items():
            if isinstance(v, Volume):
                volumes.append(v)
                out[k] = v.file
                if k == "file" and "grid" not in value:
                    out["grid"] = v.grid
            elif isinstance(v, os.PathLike):  # a pathlib.Path where a path goes
                out[k] = os.fsdecode(v)
            else:
                out[k] = _with_volumes(v, volumes)
        return out
    if isinstance(value, (list, tuple)):
        return [_with_volumes(v, volumes) for v in value]
    if isinstance(value, Volume):
        volumes.append(value)
        return value.file
    return value


# Volumes are immutable handles: a copied scene dict shares them (and keeps them alive)
Volume.__copy__ = lambda self: self
Volume.__deepcopy__ = lambda self, memo: self


def _absolute_paths(scene_dict, base_dir):
    """The scene's path fields (docs/scene-format.md "Paths": film.output, lights[].map,
    media[].file) made absolute against base_dir, in place; other values are left as they are."""
    def rebase(holder, key):
        if isinstance(holder, dict) and isinstance(holder.get(key), os.PathLike):
            holder[key] = os.fsdecode(holder[key])
        if isinstance(holder, dict) and isinstance(holder.get(key), str) and holder[key] and base_dir:
            holder[key] = os.path.normpath(os.path.join(base_dir, holder[key]))
    rebase(scene_dict.get("film"), "output")
    for section, key in (("lights", "map"), ("media", "file")):
        if isinstance(scene_dict.get(section), tuple):
            scene_dict[section] = list(scene_dict[section])
        items = scene_dict.get(section)
        for item in items if isinstance(items, list) else ():
            rebase(item, key)


def _merge_patch(target, patch):
    """RFC 7386 JSON merge patch: dicts merge key by key, None deletes, anything else replaces."""
    if not isinstance(patch, dict):
        return copy.deepcopy(patch)
    out = dict(target) if isinstance(target, dict) else {}
    for k, v in patch.items():
        if v is None:
            out.pop(k, None)
        else:
            out[k] = _merge_patch(out.get(k), v)
    return out


def _json_value(value):
    """numpy scalars and arrays (a sweep over np.linspace) as the JSON numbers and lists they hold."""
    if hasattr(value, "tolist") and type(value).__module__ == "numpy":
        return value.tolist()
    raise TypeError(f"Object of type {type(value).__name__} is not JSON serializable")


def _not_json(value, path="", numpy_ok=True):
    """The JSON path and reason of the first value JSON cannot hold (NaN, inf, a non-JSON type), or None."""
    if isinstance(value, dict):
        for k, v in value.items():
            if not isinstance(k, str):
                return f"{path or '/'}: key {k!r} is not a string"
            found = _not_json(v, f"{path}/{k}")
            if found:
                return found
        return None
    if isinstance(value, (list, tuple)):
        for i, v in enumerate(value):
            found = _not_json(v, f"{path}/{i}")
            if found:
                return found
        return None
    if hasattr(value, "tolist") and type(value).__module__ == "numpy":
        return _not_json(value.tolist(), path)
    if isinstance(value, float) and (value != value or value in (float("inf"), float("-inf"))):
        return f"{path}: {value} is not a number JSON can hold"
    if value is None or isinstance(value, (str, int, float, bool)):
        return None
    return f"{path}: a {type(value).__name__} is not a JSON value"


def _to_json(scene_dict, name):
    found = _not_json(scene_dict)
    if found:
        raise ValueError(f"{name}: {found}")
    return json.dumps(scene_dict, allow_nan=False, default=_json_value)


def load_dict(scene_dict, base_dir=None, name="<dict>"):
    """A scene from its JSON as a dict (docs/scene-format.md), validated as a scene file is; relative
    paths resolve against base_dir (default: the current folder). ValueError names the field path."""
    if not isinstance(scene_dict, dict):
        raise TypeError(f"load_dict: a dict is needed, not {type(scene_dict).__name__}")
    volumes = []
    plain = _with_volumes(scene_dict, volumes)
    text = _to_json(plain, name)
    base = os.path.abspath(base_dir or os.getcwd())
    desc = _spectrack.parse_scene(text, os.fsencode(name), os.fsencode(base))
    return Scene(desc, volumes, copy.deepcopy(scene_dict), text, base)


def load_file(path, **overrides):
    """A scene file; each keyword (a top-level section: film, render, camera, lights, media) is merged
    into the file's JSON as an RFC 7386 merge patch, e.g. ``load_file(p, film={"spp": 16})``."""
    path = os.fspath(path)
    if not overrides:
        return Scene(_spectrack.load_scene(os.fsencode(path)))  # the file system's bytes (any name)
    text = _spectrack.read_scene_text(os.fsencode(path))  # the loader's checks of the file (a USD stage, a FIFO, ...)
    try:
        doc = json.loads(text.decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as e:
        raise ValueError(f"{path}: not JSON: {e}") from None
    volumes = []
    plain = _merge_patch(doc, _with_volumes(overrides, volumes))
    text = _to_json(plain, path)
    base = os.path.dirname(os.path.abspath(path))
    desc = _spectrack.parse_scene(text, os.fsencode(path), os.fsencode(base))
    return Scene(desc, volumes, _merge_patch(doc, overrides), text, base)


def load_usd(path, frame=None, **options):
    """A scene from a USD stage (docs/usd.md); needs usd-core (``pip install usd-core``)."""
    from .usd import stage_to_dict  # imports pxr
    scene_dict, warnings_ = stage_to_dict(path, frame=frame, **options)
    import warnings
    for w in warnings_:
        warnings.warn(w, stacklevel=2)
    return load_dict(scene_dict, base_dir=os.path.dirname(os.path.abspath(path)), name=os.fspath(path))
