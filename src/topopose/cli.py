"""The ``topopose`` command (DESIGN.md, "Command line").

Each sub-command is a thin wrapper over the Python API of one stage.
Exit status: 0 all frames processed, 1 some frames failed, 2 unusable input.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from .errors import InputError

METHODS_THIN = ["d6i1d", "pkd6", "d6u", "d6i2d", "ack3"]
METHODS_MATCH = ["aha", "ha", "alignment"]


def _size(text: str) -> tuple[int, int]:
    try:
        w, h = (int(x) for x in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"--size must be WxH, e.g. 640x480, got {text!r}") from None
    return w, h


# --------------------------------------------------------------------------- handlers
def cmd_demo(a):
    from .pose.demo import run_demo

    return run_demo(a.dir, frames=a.frames, resolution=a.resolution, seed=a.seed, noise=a.noise,
                    subjects=a.subjects.split(",") if a.subjects else None)


def cmd_synth(a):
    from .capture.synth import synthesize

    out = synthesize(a.out, subject=a.subject, frames=a.frames, seed=a.seed, cameras=a.cameras,
                     size=a.size, noise=a.noise, motion=a.motion, thickness=a.thickness,
                     separated=a.separated, fps=a.fps, margin=a.margin, build=a.build)
    print(f"wrote {out}: {a.subject}, {a.frames} frames, {a.cameras} cameras ({a.motion})")
    return 0


def cmd_hull(a):
    from .capture import load_capture
    from .hull import visual_hull

    cap = load_capture(a.capture)
    vol = visual_hull(cap, a.frame, resolution=a.resolution, tolerance=a.tolerance,
                      refocus=a.refocus)
    Path(a.out).parent.mkdir(parents=True, exist_ok=True)
    vol.save(a.out)
    d = vol.diagnostics
    extra = f", {len(d['components_dropped'])} small components dropped" if d.get("components_dropped") else ""
    border = ", touches the volume border" if d.get("touches_border") else ""
    print(f"wrote {a.out}: {d.get('voxels', int(vol.data.sum()))} voxels, grid {vol.data.shape}, "
          f"voxel {vol.voxel_size:g}{extra}{border}")
    return 0


def cmd_skeleton(a):
    from .hull import Volume
    from .topology import thin

    vol = Volume.load(a.volume)
    skel = thin(vol.data, method=a.method)
    Volume(skel, vol.origin, vol.voxel_size).save(a.out)
    print(f"wrote {a.out}: {int(skel.sum())} skeleton voxels ({a.method})")
    return 0


def cmd_tree(a):
    from .hull import Volume
    from .skeleton import data_tree, tree_stats_cli

    if a.stats:
        try:
            res = [int(r) for r in a.resolutions.split(",")]
        except ValueError:
            raise InputError("--resolutions: expected integers separated by commas, "
                             f"got {a.resolutions!r}") from None
        return tree_stats_cli(a.stats, out=a.out, resolutions=res, incomplete=a.border)
    if a.skeleton is None or a.out is None:
        raise InputError("topopose tree: give SKELETON.npz and --out TREE.json (or --stats CAPTURE)")
    vol = Volume.load(a.skeleton)
    try:
        tree = data_tree(vol.data, origin=vol.origin, voxel_size=vol.voxel_size, weight=a.weight,
                         border="grid" if a.border else None)
    except InputError as exc:
        raise InputError(f"{a.skeleton}: {exc}") from None
    tree.save(a.out)
    d = tree.diagnostics
    notes = [f"{k.replace('_', ' ')}: {d[k]}" for k in ("cycles_broken", "loops", "small_cycles")
             if d.get(k)]
    if d.get("dropped_components"):
        notes.append(f"dropped components: {d['dropped_components']}")
    if d.get("border_vertex") is not None:
        notes.append(f"border vertex: {d['border_vertex']}")
    print(f"wrote {a.out}: {tree.n_vertices} vertices, {len(tree.edges)} edges, max degree "
          f"{d['max_degree']}" + (f" ({'; '.join(notes)})" if notes else ""))
    return 0


def cmd_match(a):
    from .match import Tree, align
    from .pose import load_model

    model = load_model(a.model)
    data = Tree.load(a.tree)
    data_root = data.root
    if data_root is None and getattr(model, "complete", True) is False:
        data_root = data.diagnostics.get("border_vertex")   # incomplete model: both rooted (§11.4.2)
        if data_root is not None and data_root not in set(data.vertices):
            data_root = None
    res = align(model.tree.normalized(), data.normalized(), method=a.method, cut=a.cut, data_root=data_root)
    print(res.report())
    return 0


def cmd_run(a):
    from .pose.run import run_cli

    return run_cli(a)


def cmd_view(a):
    from .viz import view_cli

    return view_cli(a)


def cmd_evaluate(a):
    from .pose.quality import evaluate_cli

    return evaluate_cli(a)


def cmd_segment(a):
    from .pose.segment import segment_cli

    return segment_cli(a)


def cmd_detect(a):
    from .pose.detect import detect_cli

    return detect_cli(a)


def cmd_cluster(a):
    from .pose.cluster import cluster_cli

    return cluster_cli(a)


def cmd_learn_model(a):
    from .kinematics import learn_model_cli

    return learn_model_cli(a)


def cmd_calib(a):
    from .capture.calib_import import calib_import_cli

    return calib_import_cli(a)


def cmd_bench(a):
    import runpy

    here = Path(__file__).resolve()
    for root in (Path.cwd(), *here.parents):
        bdir = root / "benchmarks"
        if bdir.is_dir():
            break
    else:
        raise InputError("topopose bench: no benchmarks/ folder found (run it from a source checkout)")
    scripts = sorted(p for p in bdir.glob("*.py") if not p.name.startswith("_"))
    if a.stage:
        scripts = [p for p in scripts if p.stem.startswith(a.stage)]
        if not scripts:
            raise InputError(f"topopose bench: no benchmark named {a.stage!r} in {bdir}")
    sys.path.insert(0, str(bdir))  # the scripts share benchmarks/_machine.py
    for p in scripts:
        print(f"== {p.name}", flush=True)
        sys.argv = [str(p), *(["--quick"] if a.quick else [])]
        runpy.run_path(str(p), run_name="__main__")
    return 0


# --------------------------------------------------------------------------- parser
def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="topopose", description=__doc__.splitlines()[0])
    from . import __version__

    p.add_argument("--version", action="version", version=f"topopose {__version__}")
    sub = p.add_subparsers(dest="command", required=True, metavar="COMMAND")

    s = sub.add_parser("demo", help="synthesize captures, run them, write poses and pictures")
    s.add_argument("dir", nargs="?", default="topopose-demo")
    s.add_argument("--frames", type=int, default=6)
    s.add_argument("--resolution", type=int, default=100)
    s.add_argument("--seed", type=int, default=0)
    s.add_argument("--noise", type=int, default=0, help="silhouette noise level 0-3")
    s.add_argument("--subjects", default=None,
                   help="comma-separated, default human,hand,dog,spider (also: body)")
    s.set_defaults(func=cmd_demo)

    s = sub.add_parser("synth", help="write a synthetic capture folder with ground truth")
    s.add_argument("out")
    s.add_argument("--subject", choices=["human", "hand", "dog", "spider", "body"], default="human")
    s.add_argument("--frames", type=int, default=10)
    s.add_argument("--seed", type=int, default=0)
    s.add_argument("--cameras", type=int, default=8)
    s.add_argument("--size", type=_size, default=(640, 480), help="image size WxH")
    s.add_argument("--noise", type=int, default=0, help="silhouette noise level 0-3")
    s.add_argument("--motion", choices=["random", "walk", "trot", "grasp"], default="random")
    s.add_argument("--thickness", type=float, default=1.0, help="limb thickness factor (dress, coat)")
    s.add_argument("--separated", action="store_true",
                   help="random poses only: no two non-adjacent limbs touch")
    s.add_argument("--fps", type=float, default=25.0, help="frame rate of motion sequences")
    s.add_argument("--margin", type=float, default=None,
                   help="with --separated: smallest gap between limbs, in metres (e.g. 3 voxels)")
    s.add_argument("--build", choices=["average", "heavy", "child", "lean", "random"], default=None,
                   help="body subject: proportions (default random, drawn from the seed)")
    s.set_defaults(func=cmd_synth)

    s = sub.add_parser("hull", help="volumetric visual hull of one frame")
    s.add_argument("capture")
    s.add_argument("--frame", required=True)
    s.add_argument("--resolution", type=int, default=100)
    s.add_argument("--tolerance", type=int, default=0, help="keep voxels seen by at least C-k cameras")
    s.add_argument("--refocus", action="store_true", help="centre the grid on the subject")
    s.add_argument("--out", required=True)
    s.set_defaults(func=cmd_hull)

    s = sub.add_parser("skeleton", help="curve skeleton by topology-preserving thinning")
    s.add_argument("volume")
    s.add_argument("--method", choices=METHODS_THIN, default="d6i1d")
    s.add_argument("--out", required=True)
    s.set_defaults(func=cmd_skeleton)

    s = sub.add_parser("tree", help="data tree of a curve skeleton")
    s.add_argument("skeleton", nargs="?")
    s.add_argument("--out")
    s.add_argument("--weight", choices=["length", "count"], default="length")
    s.add_argument("--stats", metavar="CAPTURE", help="tree size/degree statistics over a capture "
                   "(writes --out STATS.png, .md, .json)")
    s.add_argument("--resolutions", default="50,100,150", help="with --stats: grid resolutions")
    s.add_argument("--border", action="store_true",
                   help="incomplete model: ends on the grid border make infinite edges (thesis §7.3.3.1)")
    s.set_defaults(func=cmd_tree)

    s = sub.add_parser("match", help="align a model tree with a data tree")
    s.add_argument("model")
    s.add_argument("tree")
    s.add_argument("--method", choices=METHODS_MATCH, default="aha")
    s.add_argument("--cut", action="store_true")
    s.set_defaults(func=cmd_match)

    s = sub.add_parser("run", help="estimate the pose in every frame of a capture")
    s.add_argument("capture")
    s.add_argument("--model", default="human")
    s.add_argument("--resolution", type=int, default=100)
    s.add_argument("--threshold", type=float, default=None)
    s.add_argument("--output", default="poses.jsonl")
    s.add_argument("--trc")
    s.add_argument("--csv")
    s.add_argument("--c3d")
    g = s.add_mutually_exclusive_group()
    g.add_argument("--workers", type=int, default=1)
    g.add_argument("--scheduler")
    s.add_argument("--resume", action="store_true", help="skip the frames already in --output")
    s.add_argument("--no-constraints", action="store_true",
                   help="drop the model's coordinate constraints (acrobatics)")
    s.add_argument("--no-confidence-gate", action="store_true",
                   help="report each frame's confidence but do not let it decide 'matched'")
    s.add_argument("--tolerance", type=int, default=None,
                   help="visual hull: keep voxels seen by C-k cameras (default 1 with >= 6 cameras, else 0)")
    s.add_argument("--rerun", metavar="FILE.rrd")
    s.add_argument("--frames", help="frame range or list, e.g. 0:100 or 000001,000007, or times "
                   "in seconds, e.g. 0.5s:1.2s")
    s.add_argument("--refocus", action="store_true",
                   help="visual hull on a grid refocused on the subject every frame")
    s.add_argument("--track", action=argparse.BooleanOptionalAction, default=True,
                   help="sequences: numbered parts keep their identity over time (default on)")
    s.add_argument("--sides", action=argparse.BooleanOptionalAction, default=True,
                   help="name mirror pairs left_/right_ from geometry (default on)")
    s.add_argument("--skeleton", action=argparse.BooleanOptionalAction, default=True,
                   help="fit the full kinematic skeleton (joints; default on)")
    s.add_argument("--smooth", type=int, default=None, metavar="FRAMES",
                   help="Savitzky-Golay window smoothing the skeleton")
    s.add_argument("--bvh", help="BVH export of the fitted skeleton (Blender)")
    s.set_defaults(func=cmd_run)

    s = sub.add_parser("view", help="render one frame as a PNG")
    s.add_argument("capture")
    s.add_argument("--poses", required=True)
    s.add_argument("--frame", required=True)
    s.add_argument("--out", required=True)
    s.add_argument("--model", default=None)
    s.add_argument("--resolution", type=int, default=None)
    s.add_argument("--silhouettes", action="store_true", help="also draw silhouettes with parts reprojected")
    s.add_argument("--segmentation", action="store_true",
                   help="draw the hull segmented by body part (thesis §13.3.1.1) instead")
    s.set_defaults(func=cmd_view)

    s = sub.add_parser("evaluate", help="score poses against gt.json")
    s.add_argument("capture")
    s.add_argument("--poses", required=True)
    s.add_argument("--out", default=None, help="folder for the figures")
    s.add_argument("--tolerance", type=float, default=None)
    s.set_defaults(func=cmd_evaluate)

    s = sub.add_parser("learn-model", help="learn the model tree from a sequence (Mukasa et al.)")
    s.add_argument("capture")
    s.add_argument("--out", required=True)
    s.add_argument("--resolution", type=int, default=100)
    s.add_argument("--joints", help="write per-frame joints and segments as JSON Lines")
    s.add_argument("--frames", help="frame range or list, e.g. 0:100 or 000001,000007, or times "
                   "in seconds, e.g. 0.5s:1.2s")
    s.add_argument("--coherence", choices=["frequent", "human"], default="frequent",
                   help="coherent-interval rule: the sequence's most frequent tree signature "
                        "(default) or the paper's human rule")
    s.add_argument("--criterion", choices=["correlation", "rigidity"], default="correlation",
                   help="rigid-part clustering: velocity cross-correlation (eq. 5) or distance rigidity")
    s.set_defaults(func=cmd_learn_model)

    s = sub.add_parser("calib", help="calibration tools: import Qualisys, EasyMocap, OpenCV, "
                       "P-matrix calibrations")
    calib = s.add_subparsers(dest="calib_command", required=True, metavar="ACTION")
    c = calib.add_parser("import", help="convert calibration files to calibration.toml")
    c.add_argument("files", nargs="+", metavar="FILE")
    c.add_argument("--format", choices=["qualisys", "easymocap", "opencv", "pmatrix"],
                   default=None, help="default: detected from the files")
    c.add_argument("--out", required=True, help="calibration.toml to write")
    g = c.add_mutually_exclusive_group()
    g.add_argument("--size", type=_size, default=None,
                   help="image size WxH when the files give none (P matrices)")
    g.add_argument("--image", default=None, help="an image of the cameras: its size")
    c.set_defaults(func=cmd_calib)

    s = sub.add_parser("segment", help="label the visual hull by body part (thesis §13.3.1.1)")
    s.add_argument("capture")
    s.add_argument("--poses", required=True)
    s.add_argument("--out", required=True, help="folder: per matched frame labels .npz, mesh .ply, "
                                                "per-camera label .png")
    s.add_argument("--frames", help="comma-separated frames (default: every matched frame)")
    s.add_argument("--model", default=None)
    s.add_argument("--resolution", type=int, default=None)
    s.set_defaults(func=cmd_segment)

    s = sub.add_parser("detect", help="detect a described pose in every frame (thesis §13.3.2.1)")
    s.add_argument("poses")
    s.add_argument("expr", nargs="?", help='e.g. "(z-greatest hand_1 head) XOR (z-greatest hand_2 head)"')
    s.add_argument("--pose", help="a named pose of the library (hands-up, ask-a-question, "
                                  "wide-spread-arms, acrobatic)")
    s.add_argument("--library", help="a TOML pose library adding to the built-in one")
    s.add_argument("--list", action="store_true", help="list the library's poses")
    s.add_argument("--output", help="JSON Lines {frame, value} (default: standard output)")
    s.add_argument("--csv", help="also write frame,value as CSV")
    s.add_argument("--up", help="the capture's up axis (default: the poses header's, else +z)")
    s.set_defaults(func=cmd_detect)

    s = sub.add_parser("cluster", help="cluster frames by betweenness relations (thesis §13.3.2.2)")
    s.add_argument("poses")
    s.add_argument("--output", help="JSON Lines {frame, cluster} (default: standard output)")
    g = s.add_mutually_exclusive_group()
    g.add_argument("--clusters", type=int, help="number of clusters")
    g.add_argument("--threshold", type=float, help="cut at this distance 1 - similarity")
    s.add_argument("--auto", choices=["silhouette", "gap"], default="silhouette",
                   help="automatic cut: best mean silhouette (default) or largest gap between merge heights")
    s.add_argument("--figure", help="PNG: medoid poses and the timeline coloured by cluster")
    s.add_argument("--up", help="up axis for the figure (default: the poses header's, else +z)")
    s.set_defaults(func=cmd_cluster)

    s = sub.add_parser("bench", help="run the benchmarks beside their peers")
    s.add_argument("stage", nargs="?")
    s.add_argument("--quick", action="store_true")
    s.set_defaults(func=cmd_bench)
    return p


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except InputError as exc:
        print(f"topopose: error: {exc}".replace("\n", " "), file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("topopose: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
