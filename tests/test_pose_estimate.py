"""Per-frame helpers: cavity filling (topology: cavities go, tunnels stay)."""
import numpy as np
from scipy import ndimage

from topopose.hull import Volume
from topopose.pose.estimate import fill_cavities


def _cavities(a):
    bg, nb = ndimage.label(np.pad(~a, 1, constant_values=True))       # 6-adjacency
    return nb - 1


def test_fill_cavities_fills_pockets_keeps_tunnels():
    z, y, x = np.mgrid[:30, :30, :30]
    r = np.sqrt((x - 15) ** 2 + (y - 15) ** 2 + (z - 15) ** 2)
    shell = (r < 12) & (r > 6)                               # one cavity inside
    a = shell.copy()
    a[20:26, 3:6, 3:6] = True
    a[22, 4, 4] = False                                      # a one-voxel cavity in a block
    assert _cavities(a) == 2
    v = fill_cavities(Volume(a.copy(), (1, 2, 3), 0.5))
    assert _cavities(v.data) == 0 and v.diagnostics["cavities_filled"] == 2
    assert np.array_equal(v.data, ndimage.binary_fill_holes(a))
    np.testing.assert_allclose(v.origin, (1, 2, 3))
    # a tunnel (a ring) is not a cavity: nothing changes
    ring = np.zeros((20, 20, 5), bool)
    ring[3:17, 3:17, 1:4] = True
    ring[7:13, 7:13, :] = False
    w = fill_cavities(Volume(ring.copy(), (0, 0, 0), 1.0))
    assert np.array_equal(w.data, ring)
    assert fill_cavities(Volume(np.zeros((3, 3, 3), bool), (0, 0, 0), 1.0)).data.sum() == 0


def test_confidence_gate_default_is_on():
    """The gate is on by default with 4 and 8 cameras (measured in default_gate); an explicit
    choice wins, and the CLI's auto/on/off reach the run."""
    from types import SimpleNamespace

    from topopose.cli import build_parser
    from topopose.pose.estimate import FrameEstimator, default_gate

    assert default_gate(SimpleNamespace(cameras=[0] * 4)) and default_gate(SimpleNamespace(cameras=[0] * 8))
    from topopose.capture import synthetic_capture

    for n in (4, 8):
        cap = synthetic_capture("human", frames=1, cameras=n, size=(160, 120))
        assert FrameEstimator(cap, "human", 40).gate is True
        assert FrameEstimator(cap, "human", 40, gate=False).gate is False
    p = build_parser()
    assert p.parse_args(["run", "C"]).confidence_gate == "auto"
    assert p.parse_args(["run", "C", "--confidence-gate", "off"]).confidence_gate == "off"
