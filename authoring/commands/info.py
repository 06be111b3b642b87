"""``crowdweave info PATH [--json]``: summarise a BVH file, a take directory or a pack."""
from __future__ import annotations

import json
from pathlib import Path


def configure(p):
    p.add_argument("path", help="a .bvh file, a take directory, or a .cwpack")
    p.add_argument("--json", action="store_true", help="print JSON instead of text")


def _pack_summary(path: Path) -> dict:
    from runtime.assets import load_pack
    from runtime.motion.graph import PACK_KIND, MotionGraph
    pk = load_pack(path)
    if pk.kind == PACK_KIND:
        g = MotionGraph.load(path)
        out = {"kind": pk.kind, "version": pk.version, **g.summary()}
        if "build_report" in g.meta:
            out["build_report"] = g.meta["build_report"]
        return out
    out = {"kind": pk.kind, "version": pk.version,
           "arrays": {k: list(v.shape) for k, v in pk.arrays.items()}}
    if "frame_contacts" in pk.arrays:
        from runtime.motion.contacts import contact_summary
        out["contacts"] = contact_summary(pk.arrays["frame_contacts"], "pack")
    for k, v in pk.meta.items():
        if isinstance(v, (int, float, str, bool)):
            out[k] = v
    return out


def _take_dir_summary(path: Path) -> dict:
    from authoring.bvh import bvh_summary
    files = sorted(path.glob("*.bvh"))
    if not files:
        raise FileNotFoundError(f"{path}: no .bvh files in this directory")
    takes = [bvh_summary(f) for f in files]
    for f, t in zip(files, takes):
        sidecar = f.with_suffix(".labels.json")
        if sidecar.exists():
            from authoring.motion_graph.sources import read_contacts
            from runtime.motion.contacts import contact_summary
            c = read_contacts(sidecar, t["source_frames"])
            if c is not None:
                t["contacts"] = contact_summary(c, "labels")
    out = {"directory": str(path), "takes": len(takes),
           "frames": sum(t["frames"] for t in takes),
           "duration_s": round(sum(t["duration"] for t in takes), 2),
           "families": sorted({t["family"] for t in takes}), "files": takes}
    session = path / "session.json"
    if session.exists():
        try:
            from authoring.capture_quality import take_quality
        except ImportError:
            pass
        else:
            out["quality"] = take_quality(path)
    return out


def _print(d, indent=0):
    pad = "  " * indent
    for k, v in d.items():
        if isinstance(v, dict):
            print(f"{pad}{k}:")
            _print(v, indent + 1)
        elif isinstance(v, list) and v and isinstance(v[0], dict):
            print(f"{pad}{k}: ({len(v)})")
            for item in v:
                print(f"{pad}  - " + ", ".join(f"{a}={b}" for a, b in item.items() if not isinstance(b, (dict, list))))
        else:
            print(f"{pad}{k}: {v}")


def run(args) -> int:
    from authoring.bvh import BVHError, bvh_summary
    from authoring.commands import CLIError
    from authoring.motion_graph.sources import LabelError
    from runtime.assets import AssetError
    p = Path(args.path)
    try:
        if p.is_dir():
            d = _take_dir_summary(p)
        elif not p.exists():
            raise CLIError(f"{p}: no such file or directory")
        elif p.suffix.lower() == ".bvh":
            d = bvh_summary(p)
        elif p.suffix.lower() == ".cwpack":
            d = _pack_summary(p)
        else:
            raise CLIError(f"{p}: don't know how to summarise this (expected .bvh, .cwpack or a directory)")
    except (BVHError, AssetError, FileNotFoundError, LabelError) as e:
        raise CLIError(str(e)) from None
    if args.json:
        print(json.dumps(d, indent=2, default=str))
    else:
        report = d.pop("build_report", None)
        _print(d)
        if report is not None:
            from authoring.motion_graph.report import format_report
            print("build report:")
            for line in format_report(report["sources"], report["capabilities"]):
                print("  " + line)
    return 0
