"""`topopose learn-model`: a model tree learned from a sequence."""
from __future__ import annotations

from pathlib import Path

from topopose.errors import InputError
from topopose.kinematics.learn import MIN_COHERENT_FRAMES, learn_model


def learn_model_cli(args) -> int:
    """``topopose learn-model CAPTURE --out MODEL.toml [--resolution N] [--joints F.jsonl]
    [--frames RANGE] [--coherence frequent|human] [--criterion correlation|rigidity]``.

    Writes MODEL.toml (the reduced tree for ``topopose run``), MODEL.joints.toml (the
    full joint tree, also a valid model file) and, with ``--joints``, the per-frame joints
    and segments as JSON Lines. Exit 0 on success, 1 when no coherent interval was found
    (the best partial structure is written and the reason printed), 2 for unusable input.
    """
    import sys

    out = Path(args.out)
    if out.suffix.lower() != ".toml":
        raise InputError(f"--out {out}: the model file must end in .toml")
    from topopose.capture import load_capture

    cap = load_capture(args.capture)
    synth = (cap.gt or {}).get("synth") or {} if isinstance(cap.gt, dict) else {}
    if synth.get("motion") == "random":
        raise InputError(f"{args.capture}: learn-model needs a motion sequence, and this synthetic "
                         "capture holds independent random poses (gt.json synth.motion = 'random'): "
                         "no motion to learn the rigid parts from; try `topopose synth DIR --motion walk`")
    frames = None
    if getattr(args, "frames", None):
        from topopose.batch.run import select_frames

        frames = select_frames(cap, args.frames)
    res = learn_model(cap, resolution=args.resolution, frames=frames, progress=sys.stderr.isatty(),
                      coherence=getattr(args, "coherence", "frequent"),
                      criterion=getattr(args, "criterion", "correlation"))
    if res.model is None:
        print(f"topopose: error: {res.message or 'no structure found'}; nothing written", file=sys.stderr)
        return 1
    from topopose._paths import atomic_output

    with atomic_output(out, "--out") as tmp:
        res.model.save(tmp)
    fm = res.full_model()
    if fm is not None:
        with atomic_output(out.with_suffix(".joints.toml"), "--out") as tmp:
            fm.save(tmp)
    if getattr(args, "joints", None):
        with atomic_output(args.joints, "--joints") as tmp:
            res.write_jsonl(tmp)
    print(f"{res.diagnostics.get('builtin') or 'learned'} structure: "
          f"{len(res.full.vertices) if res.full else 0} joints, model parts "
          f"{res.model.parts if res.model else []}; coherent frames {sum(res.coherent)}/{len(res.frames)}; "
          f"wrote {out}" + (f" and {out.with_suffix('.joints.toml')}" if res.model else ""))
    if res.status != "ok":
        print(f"topopose: warning: {res.message}", file=sys.stderr)
        return 1
    longest = max((b - a for a, b in res.intervals), default=0)
    if longest < MIN_COHERENT_FRAMES:
        print(f"topopose: warning: the longest topologically coherent interval has {longest} frames "
              f"(fewer than {MIN_COHERENT_FRAMES}): too short to tell the rigid parts apart "
              "reliably (parts may be mislabelled, e.g. head and hand swapped); learn from a longer "
              "sequence of smooth motion", file=sys.stderr)
    return 0
