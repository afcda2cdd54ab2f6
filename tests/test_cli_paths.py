"""Every CLI path checked before any work or write: bad arguments and output paths
give one line on stderr and exit 2, an existing output is left byte for byte as it was,
--resume refuses a file made with another model / resolution / capture, synth refuses to mix
captures, a closed stdout ends quietly."""
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from topopose import _paths
from topopose.cli import main

SRC = str(Path(__file__).resolve().parents[1] / "src")


@pytest.fixture(scope="module")
def cap(tmp_path_factory):
    from topopose.synth import synthesize

    out = tmp_path_factory.mktemp("cap") / "human"
    synthesize(out, subject="human", frames=3, seed=1, cameras=6, size=(200, 150), separated=True)
    return out


@pytest.fixture(scope="module")
def poses(cap, tmp_path_factory):
    """A finished run (resolution 40) whose file the refused runs must leave unchanged."""
    out = tmp_path_factory.mktemp("run") / "poses.jsonl"
    assert main(["run", str(cap), "--resolution", "40", "--output", str(out)]) == 0
    return out


def one_line_exit_2(capsys, argv, *must):
    code = main(argv)
    err = capsys.readouterr().err.strip().splitlines()
    err = [e for e in err if "frame/s" not in e and "frame]" not in e]     # progress bar
    assert code == 2, (argv, code, err)
    assert len(err) == 1 and err[0].startswith("topopose: error:"), err
    for m in must:
        assert m in err[0], (m, err[0])
    return err[0]


@pytest.mark.parametrize("extra,msg", [
    (["--resolution", "0"], "--resolution"),
    (["--resolution", "100000"], "needs about"),
    (["--frames", ""], "--frames"),
    (["--frames", ","], "--frames"),
    (["--tolerance", "99"], "0..5"),
    (["--threshold", "-1"], "--threshold"),
    (["--workers", "0"], "--workers"),
])
def test_run_bad_arguments_leave_output_unchanged(cap, poses, capsys, extra, msg):
    before = poses.read_bytes()
    one_line_exit_2(capsys, ["run", str(cap), "--resolution", "40", "--output", str(poses), *extra], msg)
    assert poses.read_bytes() == before
    assert not list(poses.parent.glob("*.partial*"))


def test_run_bad_output_paths(cap, poses, tmp_path, capsys):
    before = poses.read_bytes()
    base = ["run", str(cap), "--resolution", "40"]
    one_line_exit_2(capsys, base + ["--output", str(tmp_path)], str(tmp_path), "folder")
    afile = tmp_path / "file.txt"
    afile.write_text("x")
    one_line_exit_2(capsys, base + ["--output", str(afile / "p.jsonl")], str(afile))
    for opt in ("--trc", "--csv", "--c3d"):        # exports checked before the run starts
        # (--c3d without the optional c3d package is refused for that reason first)
        one_line_exit_2(capsys, base + ["--output", str(poses), opt, str(tmp_path)], opt)
        assert poses.read_bytes() == before
    # a missing folder is not made silently
    deep = tmp_path / "a" / "b" / "p.jsonl"
    one_line_exit_2(capsys, base + ["--output", str(deep), "--frames", "0"], "--output",
                    "does not exist")
    assert not (tmp_path / "a").exists()


def test_read_only_folder_refused(cap, tmp_path, monkeypatch, capsys):
    """(Tests run as root here, where every folder is writable: os.access is what is checked.)"""
    ro = tmp_path / "ro"
    ro.mkdir()
    real = os.access
    monkeypatch.setattr(_paths.os, "access", lambda p, m: False if Path(p) == ro else real(p, m))
    one_line_exit_2(capsys, ["run", str(cap), "--output", str(ro / "p.jsonl")], str(ro), "not writable")
    one_line_exit_2(capsys, ["view", str(cap), "--poses", "x", "--frame", "0", "--out", str(ro / "x.png")],
                    "not writable")


def test_resume_refuses_another_model_resolution_or_capture(cap, poses, tmp_path, capsys):
    before = poses.read_bytes()
    head = json.loads(before.decode().splitlines()[0])
    assert head["resolution"] == 40 and head["model"] == "human" and head["capture"] == str(cap.resolve())
    base = ["run", str(cap), "--output", str(poses), "--resume"]
    one_line_exit_2(capsys, base + ["--resolution", "48"], "--resume", "resolution")
    one_line_exit_2(capsys, base + ["--resolution", "40", "--model", "dog"], "--resume", "model")
    one_line_exit_2(capsys, base + ["--resolution", "40", "--no-constraints"], "--resume", "model")
    one_line_exit_2(capsys, base + ["--resolution", "40", "--threshold", "0.1"], "--resume", "threshold")
    import shutil
    other = tmp_path / "other"
    shutil.copytree(cap, other)
    one_line_exit_2(capsys, ["run", str(other), "--output", str(poses), "--resume", "--resolution", "40"],
                    "--resume", "capture")
    assert poses.read_bytes() == before
    # the same settings resume (nothing left to do) and keep the file
    assert main(base + ["--resolution", "40"]) == 0
    assert poses.read_bytes() == before


def test_headerless_poses_still_read(cap, poses, tmp_path, capsys):
    """Files of earlier versions (no header line) are read by view / evaluate / resume."""
    from topopose.pose import read_poses

    old = tmp_path / "old.jsonl"
    old.write_text("\n".join(poses.read_text().splitlines()[1:]) + "\n")
    assert [p.frame for p in read_poses(old)] == [p.frame for p in read_poses(poses)]
    assert main(["evaluate", str(cap), "--poses", str(old), "--out", str(tmp_path / "ev")]) == 0
    assert main(["run", str(cap), "--output", str(old), "--resume", "--resolution", "40"]) == 0
    one_line_exit_2(capsys, ["run", str(cap), "--output", str(old), "--resume", "--model", "dog"],
                    "--resume")


def test_other_commands_bad_outputs(cap, poses, tmp_path, capsys):
    afile = tmp_path / "file.txt"
    afile.write_text("x")
    vol = tmp_path / "v.npz"
    assert main(["hull", str(cap), "--frame", "0", "--resolution", "24", "--out", str(vol)]) == 0
    before = vol.read_bytes()
    one_line_exit_2(capsys, ["hull", str(cap), "--frame", "0", "--out", str(tmp_path)], "folder")
    one_line_exit_2(capsys, ["hull", str(cap), "--frame", "0", "--resolution", "100000", "--out", str(vol)],
                    "100000³", "needs about")
    e_hull = one_line_exit_2(capsys, ["hull", str(cap), "--frame", "0", "--tolerance", "99", "--out", str(vol)])
    e_run = one_line_exit_2(capsys, ["run", str(cap), "--tolerance", "99", "--output", str(poses)])
    assert e_hull == e_run                         # one message for the camera count
    assert vol.read_bytes() == before
    one_line_exit_2(capsys, ["skeleton", str(vol), "--out", str(tmp_path)], "folder")
    one_line_exit_2(capsys, ["skeleton", str(vol), "--out", str(afile / "s.npz")], str(afile))
    one_line_exit_2(capsys, ["tree", str(vol), "--out", str(afile / "t.json")], str(afile))
    one_line_exit_2(capsys, ["learn-model", str(cap), "--out", str(afile / "m.toml")], str(afile))
    one_line_exit_2(capsys, ["view", str(cap), "--poses", str(poses), "--frame", "0",
                             "--out", str(afile / "x.png")], str(afile))
    one_line_exit_2(capsys, ["evaluate", str(cap), "--poses", str(poses), "--out", str(afile)], str(afile))
    one_line_exit_2(capsys, ["demo", str(afile)], str(afile))
    one_line_exit_2(capsys, ["demo", str(tmp_path / "d"), "--resolution", "100000"], "needs about")


def test_resolution_memory_estimate():
    with pytest.raises(_paths.InputError, match="1000³ grid needs about 12.0 GB"):
        _paths.check_resolution(1000, memory=4 * 10**9)
    assert _paths.check_resolution(100, memory=4 * 10**9) == 100
    with pytest.raises(_paths.InputError, match="too large"):
        _paths.check_resolution(2000, memory=10**15)


def test_atomic_output_keeps_old_file_on_error(tmp_path):
    f = tmp_path / "a.txt"
    f.write_text("old")
    with pytest.raises(RuntimeError):
        with _paths.atomic_output(f) as t:
            t.write_text("half")
            raise RuntimeError
    assert f.read_text() == "old" and os.listdir(tmp_path) == ["a.txt"]


def test_synth_refuses_existing_capture_unless_force(tmp_path, capsys):
    out = tmp_path / "c"
    assert main(["synth", str(out), "--frames", "3", "--cameras", "4", "--size", "80x60"]) == 0
    calib = (out / "calibration.toml").read_bytes()
    one_line_exit_2(capsys, ["synth", str(out), "--frames", "2", "--cameras", "4", "--size", "80x60",
                             "--seed", "5"], "--force")
    assert (out / "calibration.toml").read_bytes() == calib
    assert main(["synth", str(out), "--frames", "2", "--cameras", "4", "--size", "80x60", "--seed", "5",
                 "--force"]) == 0
    frames = sorted(p.name for p in (out / "silhouettes" / "cam_01").iterdir())
    assert frames == ["000000.png", "000001.png"]            # no stale frame 000002


def test_closed_stdout_exits_quietly(cap, poses):
    """``topopose evaluate ... | head``: no BrokenPipeError traceback."""
    env = dict(os.environ, PYTHONPATH=SRC)
    p = subprocess.Popen([sys.executable, "-m", "topopose.cli", "evaluate", str(cap), "--poses", str(poses),
                          "--out", str(poses.parent)],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env)
    p.stdout.close()                                      # the reader is gone before any output
    err = p.stderr.read().decode()
    p.wait(timeout=120)
    assert "Traceback" not in err and "BrokenPipe" not in err, err
    assert p.returncode in (0, 141)


def test_every_option_has_help():
    import argparse

    from topopose.cli import build_parser

    p = build_parser()
    assert "DESIGN.md" not in p.format_help()
    missing, todo = [], [("", p)]
    while todo:                                     # every (nested) sub-command
        name, parser = todo.pop()
        assert "DESIGN.md" not in parser.format_help()     # renders (no bad %-format)
        for a in parser._actions:
            if isinstance(a, argparse._SubParsersAction):
                todo += [(f"{name} {k}".strip(), sp) for k, sp in a.choices.items()]
            if name and not a.help and not isinstance(a, argparse._HelpAction):
                missing.append(f"{name} {a.option_strings[0] if a.option_strings else a.dest}")
    assert not missing, missing


def test_bench_runs_every_stage_into_an_untracked_folder(tmp_path, monkeypatch, capsys):
    b = tmp_path / "benchmarks"
    b.mkdir()
    (b / "a_stops.py").write_text("import sys  # '--quick' is sys.argv[1]: \"--quick\"\n"
                                   "print('a ran')\nsys.exit(3)\n")
    (b / "b_writes.py").write_text(
        "import os, pathlib, sys\nassert sys.argv[1:] in ([], ['--quick'])  # \"--quick\"\n"
        "pathlib.Path(os.environ['TOPOPOSE_BENCH_RESULTS'], 'b.md').write_text('x')\n")
    (b / "c_slow.py").write_text("import sys\nsys.exit(0 if len(sys.argv) == 1 else 2)\n")
    (b / "d_dev.py").write_text("import argparse\nap = argparse.ArgumentParser()\n"
                                "ap.add_argument('--work', required=True)\nap.parse_args()\n")
    monkeypatch.chdir(tmp_path)
    assert main(["bench", "--quick"]) == 1                  # a failed, b still ran
    out = capsys.readouterr().out
    assert "a_stops (exit 3)" in out and "1/2 benchmarks ran" in out
    assert "c_slow.py: no --quick mode, skipped" in out     # not run with an argument it refuses
    assert "d_dev.py: needs arguments, skipped" in out      # would stop at its parser
    assert main(["bench", "d"]) == 0 and "needs arguments" in capsys.readouterr().out
    assert main(["bench", "c"]) == 0
    assert (b / "results" / "quick" / "b.md").exists() and not (b / "results" / "b.md").exists()
    assert main(["bench", "b", "--save"]) == 0 and (b / "results" / "b.md").exists()
    one_line_exit_2(capsys, ["bench", "zz"], "zz")


def test_learn_model_refuses_random_poses_and_warns_on_short_sequences(cap, tmp_path, capsys):
    # `cap` holds independent random poses: nothing to learn the rigid parts from
    one_line_exit_2(capsys, ["learn-model", str(cap), "--out", str(tmp_path / "m.toml")],
                    "random poses")
    assert not (tmp_path / "m.toml").exists()
    walk = tmp_path / "walk"
    assert main(["synth", str(walk), "--motion", "walk", "--frames", "6", "--cameras", "6",
                 "--size", "200x150"]) == 0
    capsys.readouterr()
    main(["learn-model", str(walk), "--out", str(tmp_path / "w.toml"), "--resolution", "60"])
    err = capsys.readouterr().err
    assert "too short" in err or "no topologically coherent interval" in err, err


def test_few_frames_with_workers_run_in_one_process(cap, tmp_path, capsys, monkeypatch):
    import importlib

    R = importlib.import_module("topopose.batch.run")

    monkeypatch.setattr(R, "_run_dask", lambda *a, **k: (_ for _ in ()).throw(AssertionError("dask")))
    out = tmp_path / "p.jsonl"
    assert main(["run", str(cap), "--resolution", "40", "--workers", "2", "--output", str(out)]) == 0
    captured = capsys.readouterr()
    assert "faster in this process" in captured.err
    assert "frames/s" in captured.out and len(R.read_poses(out)) == 3
