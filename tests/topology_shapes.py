"""Random test volumes and topology oracles for tests/test_topology_*.py.

Oracles are independent of topopose: scipy.ndimage.label for the 26-components of X and
the 6-components of the complement (the volume padded with background), and
skimage.measure.euler_number (connectivity=3, i.e. 26/6) for the Euler characteristic.
"""
from __future__ import annotations

import numpy as np
from scipy import ndimage
from skimage.measure import euler_number

S26 = np.ones((3, 3, 3), dtype=bool)
S6 = ndimage.generate_binary_structure(3, 1)


def topology(vol: np.ndarray) -> tuple[int, int, int]:
    """(26-components of X, 6-components of the complement, Euler characteristic)."""
    p = np.pad(vol, 1)
    n26 = ndimage.label(p, structure=S26)[1]
    n6 = ndimage.label(~p, structure=S6)[1]
    return int(n26), int(n6), int(euler_number(p, connectivity=3))


def has_2x2x2_block(vol: np.ndarray) -> bool:
    v = vol
    b = v[:-1, :-1, :-1] & v[1:, :-1, :-1] & v[:-1, 1:, :-1] & v[:-1, :-1, 1:]
    b &= v[1:, 1:, :-1] & v[1:, :-1, 1:] & v[:-1, 1:, 1:] & v[1:, 1:, 1:]
    return bool(b.any())


def neighbour_counts(vol: np.ndarray) -> np.ndarray:
    k = np.ones((3, 3, 3), dtype=np.int32)
    k[1, 1, 1] = 0
    return ndimage.convolve(vol.astype(np.int32), k, mode="constant")


# ----------------------------------------------------------------------------- shapes
def _grid(n):
    return np.indices(n).astype(float)


def blob(rng, n=None):
    n = n or tuple(rng.integers(7, 15, 3))
    f = ndimage.gaussian_filter(rng.normal(size=n), sigma=rng.uniform(1.0, 2.0))
    return f > np.quantile(f, rng.uniform(0.4, 0.75))


def torus(rng):
    n = tuple(rng.integers(12, 17, 3))
    g = _grid(n) - (np.array(n)[:, None, None, None] - 1) / 2
    a = rng.normal(size=3)
    a /= np.linalg.norm(a)
    u = np.cross(a, rng.normal(size=3))
    u /= np.linalg.norm(u)
    w = np.cross(a, u)
    x, y, z = (np.tensordot(e, g, axes=(0, 0)) for e in (u, w, a))
    R = rng.uniform(3.0, min(n) / 2 - 2.5)
    r = rng.uniform(1.0, min(2.2, R - 0.5))
    return (np.hypot(x, y) - R) ** 2 + z ** 2 <= r ** 2


def shell(rng):
    n = tuple(rng.integers(10, 16, 3))
    g = _grid(n) - (np.array(n)[:, None, None, None] - 1) / 2
    scale = rng.uniform(0.8, 1.2, 3)[:, None, None, None]
    d = np.sqrt(((g * scale) ** 2).sum(0))
    R = min(n) / 2 - 1
    v = (d <= R) & (d >= R - rng.uniform(1.2, 2.5))
    for _ in range(rng.integers(0, 3)):  # punch holes
        c = rng.integers(0, n)
        v[tuple(slice(max(0, ci - 1), ci + 2) for ci in c)] = False
    return v


def knot(rng):
    """A tube around a trefoil knot (or an unknotted loop)."""
    n = tuple(rng.integers(15, 19, 3))
    t = np.linspace(0, 2 * np.pi, 400)
    if rng.random() < 0.7:
        c = np.stack([np.sin(t) + 2 * np.sin(2 * t), np.cos(t) - 2 * np.cos(2 * t), -np.sin(3 * t)], 1)
    else:
        c = np.stack([np.cos(t) * 2.5, np.sin(t) * 2.5, 0.5 * np.sin(2 * t)], 1)
    c = c / np.abs(c).max(0) * (np.array(n) / 2 - 2.5) + (np.array(n) - 1) / 2
    g = _grid(n).reshape(3, -1).T
    r = rng.uniform(0.9, 1.6)
    d2 = np.full(len(g), np.inf)
    for i in range(0, len(c), 4):
        d2 = np.minimum(d2, ((g - c[i]) ** 2).sum(1))
    return (d2 <= r * r).reshape(n)


def noise(rng):
    n = tuple(rng.integers(5, 10, 3))
    return rng.random(n) < rng.uniform(0.3, 0.75)


GENERATORS = {"blob": blob, "torus": torus, "shell": shell, "knot": knot, "noise": noise}


def random_volumes(count: int, seed: int = 0):
    """``count`` random volumes cycling through the generators (non-empty)."""
    rng = np.random.default_rng(seed)
    names = list(GENERATORS)
    out = []
    i = 0
    while len(out) < count:
        v = GENERATORS[names[i % len(names)]](rng)
        i += 1
        if v.any():
            out.append(v)
    return out


def pack(volumes, gap: int = 2):
    """Place volumes side by side (separated by ``gap`` background voxels) in one array.

    Thinning is local (26-neighbourhoods), so thinning the pack equals thinning each
    volume alone; returns the pack and each volume's slices.
    """
    k = int(np.ceil(np.sqrt(len(volumes))))
    rows = [volumes[i:i + k] for i in range(0, len(volumes), k)]
    sx = max(v.shape[0] for v in volumes) + gap
    sy = max(v.shape[1] for v in volumes) + gap
    sz = max(v.shape[2] for v in volumes) + gap
    big = np.zeros((len(rows) * sx + gap, k * sy + gap, sz + gap), dtype=bool)
    slices = []
    for r, row in enumerate(rows):
        for c, v in enumerate(row):
            x0, y0 = gap + r * sx, gap + c * sy
            sl = (slice(x0, x0 + v.shape[0]), slice(y0, y0 + v.shape[1]), slice(gap, gap + v.shape[2]))
            big[sl] = v
            slices.append(sl)
    return big, slices
