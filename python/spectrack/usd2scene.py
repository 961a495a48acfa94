"""python3 -m spectrack.usd2scene STAGE.usda -o SCENE.json: a USD stage's volumes, camera and
lights as a spectrack scene file (docs/usd.md); warnings name what is not mapped."""
import argparse
import json
import os
import sys


def main(argv=None):
    ap = argparse.ArgumentParser(prog="python3 -m spectrack.usd2scene", description=__doc__.splitlines()[0])
    ap.add_argument("stage")
    ap.add_argument("-o", "--output", required=True, help="the scene file to write (.json)")
    ap.add_argument("--frame", type=float, help="the time code (default: the stage's default time)")
    ap.add_argument("--camera", help="a camera prim path (default: the first camera)")
    ap.add_argument("--width", type=int, default=512)
    ap.add_argument("--spp", type=int, default=64)
    ap.add_argument("--sigma-t", type=float, default=1.0, help="extinction per unit density per stage unit")
    ap.add_argument("--albedo", type=float, default=0.8)
    ap.add_argument("--temperature-scale", type=float, default=1.0, help="kelvin per unit of a temperature field")
    ap.add_argument("--emission-scale", type=float, default=1.0, help="a multiplier of the emission")
    ap.add_argument("--blackbody-normalization", choices=("peak", "luminance", "none"), default="peak",
                    help="a blackbody's normalisation (docs/scene-format.md)")
    ap.add_argument("--search-path", action="append", default=[], help="a folder for files not next to the stage")
    ap.add_argument("--asset", action="append", default=[], metavar="AUTHORED=FILE",
                    help="the file of an asset path the stage authors (repeatable)")
    a = ap.parse_args(argv)
    assets = {}
    for pair in a.asset:
        authored, sep, real = pair.partition("=")
        if not sep or not authored or not real:
            ap.error(f"--asset {pair}: give AUTHORED=FILE")
        assets[authored] = real
    try:
        from .usd import stage_to_dict
        scene, warnings = stage_to_dict(a.stage, frame=a.frame, camera=a.camera, width=a.width, spp=a.spp,
                                        sigma_t=a.sigma_t, albedo=a.albedo, temperature_scale=a.temperature_scale,
                                        emission_scale=a.emission_scale,
                                        blackbody_normalization=a.blackbody_normalization,
                                        search_paths=a.search_path, assets=assets)
    except (ImportError, ValueError, TypeError, OSError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 1
    for w in warnings:
        print(f"warning: {w}", file=sys.stderr)
    # files relative to the scene file's folder, as a scene file resolves them
    base = os.path.dirname(os.path.abspath(a.output))
    for m in scene["media"]:
        m["file"] = os.path.relpath(m["file"], base)
    for lt in scene["lights"]:
        if "map" in lt:
            lt["map"] = os.path.relpath(lt["map"], base)
    try:  # the scene as `spectrack render` will read it: a value it refuses is refused here, not written
        from . import load_dict
        load_dict(scene, base_dir=base, name=a.output)
    except (ImportError, ValueError, TypeError) as e:
        print(f"error: {a.stage}: the stage maps to a scene spectrack refuses: {e}", file=sys.stderr)
        return 1
    try:
        with open(a.output, "w", encoding="utf-8") as f:
            json.dump(scene, f, indent=2)
            f.write("\n")
    except OSError as e:
        print(f"error: {a.output}: cannot write the scene: {e.strerror}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
