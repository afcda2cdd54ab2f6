"""topopose: markerless pose initialization from multi-camera silhouettes (visual hull, thinning, tree alignment).

Each sub-command is a thin wrapper over the Python API of one stage.
Exit status: 0 all frames processed, 1 some frames failed, 2 unusable input.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from topopose import _paths
from topopose.errors import InputError

METHODS_THIN = ["d6i1d", "pkd6", "d6u", "d6i2d", "ack3"]
METHODS_MATCH = ["aha", "ha", "alignment"]


#: the largest image side a size option takes (pixels)
MAX_IMAGE_SIDE = 16384


def _size(text: str) -> tuple[int, int]:
    try:
        w, h = (int(x) for x in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"--size must be WxH, e.g. 640x480, got {text!r}") from None
    if not (0 < w <= MAX_IMAGE_SIDE and 0 < h <= MAX_IMAGE_SIDE):
        raise argparse.ArgumentTypeError(f"--size: {text!r}: width and height must be 1.."
                                         f"{MAX_IMAGE_SIDE} pixels")
    return w, h


class _Parser(argparse.ArgumentParser):
    """Argument errors in one line (``topopose: error: ...``), exit 2, as every other error."""

    def error(self, message):
        self.exit(2, f"topopose: error: {self.prog}: {message} (see {self.prog} --help)\n")


def _npz(path) -> Path:
    """Volume files end in .npz (numpy adds it otherwise)."""
    p = Path(path)
    return p if p.suffix == ".npz" or p.is_dir() else p.with_name(p.name + ".npz")


# --------------------------------------------------------------------------- handlers
def cmd_demo(a):
    from topopose.batch.demo import run_demo

    _paths.check_number(a.frames, "--frames", low=1, integer=True)
    _paths.check_resolution(a.resolution)
    _paths.writable_folder(a.dir, "DIR")

    return run_demo(a.dir, frames=a.frames, resolution=a.resolution, seed=a.seed, noise=a.noise,
                    subjects=a.subjects.split(",") if a.subjects else None)


def cmd_synth(a):
    from topopose.synth.capture import synthesize

    _paths.check_number(a.cameras, "--cameras", low=1, high=256, integer=True)
    _paths.check_number(a.thickness, "--thickness", above=0, high=10)
    _paths.check_number(a.fps, "--fps", above=0, high=10000)
    _paths.check_number(a.margin, "--margin", low=0, high=1)
    _paths.check_number(a.noise, "--noise", low=0, high=3, integer=True)
    n = _paths.check_number(a.frames, "--frames", low=1, integer=True)
    need = float(n) * a.cameras * a.size[0] * a.size[1] * 2     # masks and their PNG bytes, held
    avail = _paths.available_memory()                           # until written
    if avail is not None and need > avail:
        raise InputError(f"--frames: {n} frames of {a.cameras} cameras at {a.size[0]}x{a.size[1]} "
                         f"need about {_paths._gb(need)} of memory, {_paths._gb(avail)} available")
    _paths.writable_folder(a.out, "OUT")
    old = [p for p in ("calibration.toml", "silhouettes", "images", "gt.json") if (Path(a.out) / p).exists()]
    if old and not a.force:
        raise InputError(f"synth: {a.out} already holds a capture ({', '.join(old)}); "
                         "give --force to replace it, or another folder")
    out = synthesize(a.out, subject=a.subject, frames=a.frames, seed=a.seed, cameras=a.cameras,
                     size=a.size, noise=a.noise, motion=a.motion, thickness=a.thickness,
                     separated=a.separated, fps=a.fps, margin=a.margin, build=a.build,
                     pose=a.pose)
    print(f"wrote {out}: {a.subject}, {a.frames} frames, {a.cameras} cameras ({a.motion})")
    return 0


def cmd_hull(a):
    from topopose.capture import load_capture
    from topopose.hull import visual_hull

    _paths.check_resolution(a.resolution)
    out = _paths.writable_output(_npz(a.out), "--out", inputs=_paths.capture_inputs(a.capture))
    cap = load_capture(a.capture)
    tolerance = _paths.check_tolerance(a.tolerance, len(cap.cameras))
    vol = visual_hull(cap, a.frame, resolution=a.resolution, tolerance=tolerance,
                      refocus=a.refocus)
    with _paths.atomic_output(out, "--out") as tmp:
        vol.save(tmp)
    d = vol.diagnostics
    extra = f", {len(d['components_dropped'])} small components dropped" if d.get("components_dropped") else ""
    border = ", touches the volume border" if d.get("touches_border") else ""
    print(f"wrote {a.out}: {d.get('voxels', int(vol.data.sum()))} voxels, grid {vol.data.shape}, "
          f"voxel {vol.voxel_size:g}{extra}{border}")
    return 0


def cmd_skeleton(a):
    from topopose.hull import Volume
    from topopose.topology import thin

    out = _paths.writable_output(_npz(a.out), "--out", inputs=[("VOLUME", a.volume)])
    vol = Volume.load(a.volume)
    skel = thin(vol.data, method=a.method)
    with _paths.atomic_output(out, "--out") as tmp:
        Volume(skel, vol.origin, vol.voxel_size).save(tmp)
    print(f"wrote {a.out}: {int(skel.sum())} skeleton voxels ({a.method})")
    return 0


def cmd_tree(a):
    from topopose.hull import Volume
    from topopose.skeleton import data_tree, tree_stats_cli

    if a.stats:
        try:
            res = [int(r) for r in a.resolutions.split(",")]
        except ValueError:
            raise InputError("--resolutions: expected integers separated by commas, "
                             f"got {a.resolutions!r}") from None
        if a.out is not None:                # the figure, and the table and numbers beside it
            png = Path(a.out).with_suffix(".png")
            _paths.check_outputs({"--out": png, "--out (.md)": png.with_suffix(".md"),
                                  "--out (.json)": png.with_suffix(".json")},
                                 _paths.capture_inputs(a.stats))
        return tree_stats_cli(a.stats, out=a.out, resolutions=res, incomplete=a.border)
    if a.skeleton is None or a.out is None:
        raise InputError("topopose tree: give SKELETON.npz and --out TREE.json (or --stats CAPTURE)")
    _paths.writable_output(a.out, "--out", inputs=[("SKELETON", a.skeleton)])
    vol = Volume.load(a.skeleton)
    try:
        tree = data_tree(vol.data, origin=vol.origin, voxel_size=vol.voxel_size, weight=a.weight,
                         border="grid" if a.border else None)
    except InputError as exc:
        raise InputError(f"{a.skeleton}: {exc}") from None
    with _paths.atomic_output(a.out, "--out") as tmp:
        tree.save(tmp)
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
    from topopose.match import Tree, align
    from topopose.pose import load_model

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
    from topopose.cli.run import run_cli

    return run_cli(a)


def cmd_view(a):
    from topopose.cli.view import view_cli

    _paths.writable_output(a.out, "--out", suffix=(".png", ".pdf", ".svg", ".jpg", ".jpeg"),
                           inputs=[*_paths.capture_inputs(a.capture), ("--poses", a.poses),
                                   ("--model", _paths.file_input(a.model))])

    return view_cli(a)


def cmd_evaluate(a):
    from topopose.cli.run import evaluate_cli

    if a.out:
        _paths.writable_folder(a.out, "--out", inputs=_paths.capture_inputs(a.capture))

    return evaluate_cli(a)


def cmd_segment(a):
    from topopose.cli.apps import segment_cli

    return segment_cli(a)


def cmd_detect(a):
    from topopose.cli.apps import detect_cli

    return detect_cli(a)


def cmd_cluster(a):
    from topopose.cli.apps import cluster_cli

    return cluster_cli(a)


def cmd_learn_model(a):
    from topopose.cli.learn import learn_model_cli

    _paths.check_resolution(a.resolution)
    out = Path(a.out)
    _paths.check_outputs({"--out": out, "--out (.joints.toml)": out.with_suffix(".joints.toml"),
                          "--joints": a.joints}, _paths.capture_inputs(a.capture))

    return learn_model_cli(a)


def cmd_calib(a):
    from topopose.cli.calib import calib_import_cli

    return calib_import_cli(a)


def cmd_bench(a):
    import os
    import subprocess

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
    needs = [p for p in scripts if "required=True" in p.read_text(encoding="utf-8")]
    for p in needs:                          # scripts that need a data path
        print(f"== {p.name}: needs arguments, skipped (python benchmarks/{p.name} --help)")
    scripts = [p for p in scripts if p not in needs]
    if a.quick:                              # a script without a quick mode would run in full
        slow = [p for p in scripts if '"--quick"' not in p.read_text(encoding="utf-8")]
        for p in slow:
            print(f"== {p.name}: no --quick mode, skipped (run it without --quick)")
        scripts = [p for p in scripts if p not in slow]
    # results go to the tracked benchmarks/results/ only with --save; else to an untracked
    # folder (benchmarks/results/quick/ is ignored by git)
    out = bdir / "results" if a.save else bdir / "results" / "quick"
    if bdir.is_dir() and os.access(bdir, os.W_OK):
        (bdir / "results").mkdir(exist_ok=True)      # the checkout's own folder
    _paths.writable_folder(out, "benchmarks/results")
    env = dict(os.environ, TOPOPOSE_BENCH_RESULTS=str(out))
    src = str(here.parents[1])               # the package the scripts import: this one
    env["PYTHONPATH"] = src + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
    failed = []
    for p in scripts:                        # each in its own process: one failing (or calling
        print(f"== {p.name}", flush=True)    # sys.exit) does not stop the others
        r = subprocess.run([sys.executable, str(p), *(["--quick"] if a.quick else [])], env=env,
                           cwd=str(bdir.parent))
        if r.returncode != 0:
            failed.append(f"{p.stem} (exit {r.returncode})")
    print(f"bench: {len(scripts) - len(failed)}/{len(scripts)} benchmarks ran; results in {out}"
          + (f"; failed: {', '.join(failed)}" if failed else ""))
    return 1 if failed else 0


# --------------------------------------------------------------------------- help texts
#: help of the options declared without one, per (sub-command, option); options shared by many
#: sub-commands under (None, option). Filled in by build_parser (so the parser blocks stay short).
HELP = {
    (None, "capture"): "capture folder (calibration.toml, silhouettes/ or images/, optional capture.toml)",
    (None, "--frames"): "frame range (START:STOP[:STEP], indices) or comma-separated frame names",
    (None, "--resolution"): "voxels along the longest side of the capture volume (default %(default)s)",
    (None, "--seed"): "random seed (default %(default)s)",
    (None, "--out"): "output file",
    (None, "--frame"): "frame name, or its index in the capture",
    (None, "--model"): "model tree: human, hand, dog, spider or a model TOML file",
    (None, "--poses"): "poses file written by `topopose run` (JSON Lines)",
    (None, "--method"): "algorithm (default %(default)s)",
    ("demo", "dir"): "output folder (default %(default)s); each subject's capture, poses and pictures",
    ("demo", "--frames"): "frames per subject (default %(default)s)",
    ("synth", "out"): "capture folder to write (refused if it already holds a capture, see --force)",
    ("synth", "--subject"): "synthetic subject (default %(default)s)",
    ("synth", "--frames"): "number of frames (default %(default)s)",
    ("synth", "--cameras"): "number of cameras on a ring around the volume (default %(default)s)",
    ("synth", "--motion"): "random: an unrelated random pose each frame; random-smooth (human, "
                           "body): a continuous motion through random poses, eased between "
                           "keyframes every 0.8-1.5 s; or a smooth gait (walk: human, dog, "
                           "spider; trot: dog; grasp: hand); hang, hips, fold, jump, crouch "
                           "(body): as random-smooth, the limbs touching the body",
    ("hull", "--out"): "volume file to write (.npz)",
    ("skeleton", "volume"): "volume file (.npz) written by `topopose hull`",
    ("skeleton", "--method"): "thinning: d6i1d (curve skeleton, the pipeline's), pkd6, d6u "
                              "(ultimate), d6i2d (surface), ack3 (default %(default)s)",
    ("skeleton", "--out"): "skeleton file to write (.npz)",
    ("tree", "skeleton"): "skeleton file (.npz) written by `topopose skeleton`",
    ("tree", "--out"): "tree file to write (.json); with --stats: the figure STATS.png (.md, .json beside)",
    ("tree", "--weight"): "edge weight: branch length in capture units, or voxel count "
                          "(default %(default)s)",
    ("match", "model"): "model tree: human, hand, dog, spider or a model TOML file",
    ("match", "tree"): "data tree (.json) written by `topopose tree`",
    ("match", "--method"): "aha (asymmetric homeomorphic alignment), ha (homeomorphic) or "
                           "alignment (default %(default)s)",
    ("match", "--cut"): "allow free removal of data subtrees (thesis §9.6)",
    ("run", "--threshold"): "AHA distance threshold T_d above which a frame is rejected "
                            "(default: the model's)",
    ("run", "--output"): "poses file (JSON Lines, one header line then one line per frame; "
                         "an existing file is replaced only when the run completes) (default "
                         "%(default)s)",
    ("run", "--trc"): "also export the matched frames as TRC (OpenSim, metres, Y up)",
    ("run", "--csv"): "also export the matched frames as a wide CSV (<part>_x, _y, _z)",
    ("run", "--c3d"): "also export the matched frames as C3D (pip install topopose[c3d])",
    ("run", "--workers"): "run the frames in N local worker processes (default %(default)s)",
    ("run", "--scheduler"): "address of a Dask scheduler (tcp://HOST:8786) to run the frames on",
    ("run", "--rerun"): "record the run for the rerun viewer (pip install topopose[rerun])",
    ("view", "--out"): "picture to write (.png)",
    ("view", "--resolution"): "hull grid (default: the one recorded in the poses)",
    ("view", "--model"): "model tree (default: guessed from the poses' parts)",
    ("evaluate", "--out"): "folder for the figures (default: beside the poses file)",
    ("learn-model", "--out"): "model file to write (.toml); MODEL.joints.toml is written beside",
    ("calib import", "files"): "calibration files to convert (Qualisys .qca.txt, EasyMocap "
                               "intri/extri.yml, OpenCV FileStorage, P matrices)",
    (None, "poses"): "poses file written by `topopose run` (JSON Lines)",
    ("bench", "stage"): "benchmark to run (hull, thinning, tree, alignment_speed, ...; default all)",
    ("bench", "--quick"): "small inputs, a few minutes in all (scripts without a quick mode "
                          "are skipped)",
}


def _fill_help(parser: argparse.ArgumentParser, name=None) -> None:
    """Give every option of every sub-command (nested ones too) a help text, from HELP when it
    has none (``name``: the sub-command, e.g. "run" or "calib import")."""
    for a in parser._actions:
        if name is not None and a.help is None and not isinstance(a, argparse._HelpAction):
            key = a.option_strings[0] if a.option_strings else a.dest
            a.help = HELP.get((name, key), HELP.get((None, key)))
            if a.help is None and isinstance(a, argparse._SubParsersAction):
                a.help = "one of: " + ", ".join(a.choices)
        if isinstance(a, argparse._SubParsersAction):
            for sub, sp in a.choices.items():
                _fill_help(sp, sub if name is None else f"{name} {sub}")


# --------------------------------------------------------------------------- parser
def build_parser() -> argparse.ArgumentParser:
    p = _Parser(prog="topopose", description=__doc__.splitlines()[0])
    from topopose import __version__

    p.add_argument("--version", action="version", version=f"topopose {__version__}")
    sub = p.add_subparsers(dest="command", required=True, metavar="COMMAND")

    _add_stage_commands(sub)
    _add_run_command(sub)
    _add_other_commands(sub)
    _fill_help(p)
    return p


def _add_stage_commands(sub):
    """``demo``, ``synth`` and one command per pipeline stage: ``hull``, ``skeleton``, ``tree``,
    ``match``."""
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
    s.add_argument("--motion", choices=["random", "random-smooth", "walk", "trot", "grasp", "hang",
                                        "hips", "fold", "jump", "crouch"],
                   default="random")
    s.add_argument("--thickness", type=float, default=1.0, help="limb thickness factor (dress, coat)")
    s.add_argument("--separated", action="store_true",
                   help="random poses only: no two non-adjacent limbs touch")
    s.add_argument("--fps", type=float, default=25.0, help="frame rate of motion sequences")
    s.add_argument("--margin", type=float, default=None,
                   help="with --separated: smallest gap between limbs, in metres (e.g. 3 voxels)")
    s.add_argument("--build", choices=["average", "heavy", "child", "lean", "random"], default=None,
                   help="body subject: proportions (default random, drawn from the seed)")
    s.add_argument("--pose", default="any",
                   help="body subject, random poses: one pose family, any (default), feet_out, "
                        "feet_in, twist, crouch, kneel, one_leg, arms_crossed or lying")
    s.add_argument("--force", "--overwrite", dest="force", action="store_true",
                   help="replace the capture already in OUT (its frames are deleted first)")
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


def _add_run_command(sub):
    """``run``: every frame of a capture."""
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
    s.add_argument("--confidence-gate", choices=["auto", "on", "off"], default="auto",
                   help="human model: 'matched' also needs the silhouettes explained and the AHA "
                        "distance within T_d, or above it the arcs in the model's proportions; "
                        "auto (default): on, off with --no-constraints (chosen on upright "
                        "subjects)")
    s.add_argument("--tolerance", type=int, default=None,
                   help="visual hull: keep voxels seen by C-k cameras (default 1 with >= 6 cameras, else 0)")
    s.add_argument("--rerun", metavar="FILE.rrd")
    s.add_argument("--frames", help="frame range or list, e.g. 0:100 or 000001,000007, or times "
                   "in seconds, e.g. 0.5s:1.2s")
    s.add_argument("--refocus", action="store_true",
                   help="visual hull on a grid refocused on the subject every frame")
    s.add_argument("--thickness", type=float, default=None,
                   help="weight of the parts' thickness in the arc cost (human model; default 1, "
                        "0: off)")
    s.add_argument("--track", action=argparse.BooleanOptionalAction, default=True,
                   help="sequences: numbered parts keep their identity over time (default on)")
    s.add_argument("--sides", action=argparse.BooleanOptionalAction, default=True,
                   help="name mirror pairs left_/right_ from geometry (default on)")
    s.add_argument("--skeleton", action=argparse.BooleanOptionalAction, default=True,
                   help="fit the full kinematic skeleton (joints; default on)")
    s.add_argument("--smooth", type=int, default=None, metavar="FRAMES",
                   help="Savitzky-Golay window smoothing the skeleton over runs of "
                        "continuing motion (default 0.36 s: 9 frames at 25 frames/s, 21 at "
                        "60; 0: off)")
    s.add_argument("--bvh", help="BVH export of the fitted skeleton (Blender)")
    s.add_argument("--trim", action=argparse.BooleanOptionalAction, default=None,
                   help="hands moved back out of the hull's phantom volume, where the "
                        "silhouettes' evidence ends (default on)")
    s.add_argument("--centre", action=argparse.BooleanOptionalAction, default=None,
                   help="the limbs' skeleton curves moved onto the silhouettes' centre lines "
                        "for the skeleton's fit, recorded per frame (default on)")
    s.add_argument("--consistency", action=argparse.BooleanOptionalAction, default=None,
                   help="sequences of one subject: 'matched' decided by agreement with the "
                        "neighbouring frames and the silhouettes the placed model explains "
                        "instead of the confidence gate; --no-consistency: the gate alone "
                        "(default: both, a frame is matched when the gate matches it or, "
                        "rejected by the gate alone, it is consistent with the run)")
    s.add_argument("--support", action="store_const", const=True, default=None,
                   help="per frame: reject a matched frame whose silhouettes the placed model "
                        "leaves unexplained (more than a fixed share of the silhouettes' "
                        "pixels; default off)")
    s.add_argument("--support-replace", dest="support", action="store_const", const="replace",
                   help="as --support, instead of the confidence gate: a frame the gate alone "
                        "rejected is matched when its silhouettes are explained")
    s.set_defaults(func=cmd_run)


def _add_other_commands(sub):
    """``view``, ``evaluate``, ``learn-model``, ``calib``, the applications and ``bench``."""
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
    g = s.add_mutually_exclusive_group()
    g.add_argument("--tolerance", type=float, default=None,
                   help="a part is right within this fraction of the subject height (gt.json "
                        "'height') of its gt segment, the same for every part (default: 0.1, "
                        "junctions 1.5x: the thesis study)")
    g.add_argument("--tolerance-m", type=float, default=None,
                   help="the same as an absolute distance in capture units (metres)")
    s.add_argument("--junction-factor", type=float, default=None,
                   help="junction parts (torso, crotch) get this times the tolerance (default 1 "
                        "with --tolerance/--tolerance-m, else 1.5)")
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
    s.add_argument("--margin", type=float, default=0.0,
                   help="position uncertainty (capture units): a relation that moving one of its "
                        "parts this far flips is undecided (value null); default 0 (off)")
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
    s.add_argument("--save", action="store_true",
                   help="write to the tracked benchmarks/results/ (default: benchmarks/results/quick/, "
                        "ignored by git)")
    s.set_defaults(func=cmd_bench)


def _quiet_broken_pipe() -> int:
    """stdout closed early (``topopose evaluate ... | head``): exit quietly, as Unix tools do."""
    import os

    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())      # no second error when Python flushes stdout
    except (OSError, ValueError):
        pass
    return 141


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    from topopose._quiet import one_line_warnings

    try:
        with one_line_warnings():        # ours one line each; other packages' dropped
            return int(args.func(args) or 0)
    except InputError as exc:
        print(f"topopose: error: {exc}".replace("\n", " "), file=sys.stderr)
        return 2
    except BrokenPipeError:
        return _quiet_broken_pipe()
    except KeyboardInterrupt as exc:
        # what the interrupted command kept, in the same line (run: the file left as it was)
        notes = "; ".join(getattr(exc, "__notes__", ()))
        print("topopose: interrupted" + (f": {notes}" if notes else ""), file=sys.stderr)
        return 130
    except OSError as exc:
        if exc.filename is None:
            raise
        # a path the user gave that a handler did not check up front: still one line, exit 2
        print(f"topopose: error: {exc.filename}: {exc.strerror or exc}".replace("\n", " "),
              file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
