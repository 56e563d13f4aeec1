"""Generate the pinna meshes of the Musashi head (``assets/pinna_left.stl``, ``pinna_right.stl``).

The pinna is a closed, watertight solid: an ear-shaped outline in the sagittal plane,
extruded outward from the head with a relief on its outer face (helix rim, antihelix
ridge, tragus, and the concha bowl around the ear-canal entrance). The mesh origin is the
ear-canal entrance, so the mesh geom sits at the ``ear_left`` / ``ear_right`` site with no
offset. Axes are the head's: x forward, y outward (left ear: +y; right ear: -y, mirrored),
z up. Units: metres.

Dimensions follow an adult pinna (height 62 mm, width 34 mm, protrusion about 20 mm at the
helix), the size of KEMAR's DB-061 "small" pinna used by the bundled MIT KEMAR HRTF.

Run from the repository root; output is deterministic (byte-identical on rerun)::

    .venv/bin/python assets/musashi_head/make_meshes.py
"""

from __future__ import annotations

import argparse
import struct
from pathlib import Path

import numpy as np

N_THETA = 72
"""Points around the outline."""

N_RING = 16
"""Rings from the canal entrance (rho = 0) to the outline (rho = 1)."""


def outline(theta: np.ndarray) -> np.ndarray:
    """Distance (m) from the canal entrance to the pinna's outline at polar angle ``theta``.

    ``theta`` is measured in the sagittal plane from +x (forward) toward +z (up). The outline
    is an ellipse 34 x 62 mm centred 9 mm behind and 13 mm above the canal, tilted back by
    15 deg (the pinna's usual inclination), so the ear extends mostly up and back.
    """
    centre = np.array([-0.009, 0.013])
    a, b, tilt = 0.017, 0.031, np.deg2rad(15.0)
    # Ray from the canal (origin) in direction d: solve |M (t d - c)| = 1 for t > 0, where
    # M maps the tilted ellipse to the unit circle.
    rot = np.array([[np.cos(tilt), np.sin(tilt)], [-np.sin(tilt), np.cos(tilt)]])
    scale = np.diag([1.0 / a, 1.0 / b])
    m = scale @ rot
    d = np.stack([np.cos(theta), np.sin(theta)], axis=-1)
    md = d @ m.T
    mc = m @ centre
    qa = np.sum(md * md, axis=-1)
    qb = -2.0 * md @ mc
    qc = mc @ mc - 1.0
    return (-qb + np.sqrt(qb * qb - 4.0 * qa * qc)) / (2.0 * qa)


def _bump(x: np.ndarray, centre: float, width: float) -> np.ndarray:
    return np.exp(-0.5 * ((x - centre) / width) ** 2)


def _window(theta: np.ndarray, centre_deg: float, half_width_deg: float) -> np.ndarray:
    """Smooth angular window: 1 at ``centre_deg``, 0 beyond ``half_width_deg`` from it."""
    d = np.angle(np.exp(1j * (theta - np.deg2rad(centre_deg))))
    x = np.clip(np.abs(d) / np.deg2rad(half_width_deg), 0.0, 1.0)
    return 0.5 * (1.0 + np.cos(np.pi * x))


def relief(rho: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """Thickness (m) of the pinna above its back face at radial fraction ``rho`` (0..1).

    A thin concha floor around the canal; the helix rim rolled along the upper and rear
    outline; the antihelix ridge inside it; a thick, rimless lobe at the bottom; and the
    tragus flap just in front of the canal.
    """
    helix = _window(theta, 130.0, 125.0)
    antihelix = _window(theta, 135.0, 80.0)
    lobe = _window(theta, 268.0, 45.0)
    tragus = _window(theta, 5.0, 40.0)
    t = 0.0015
    t = t + 0.0075 * _bump(rho, 0.88, 0.07) * helix
    t = t + 0.0050 * _bump(rho, 0.62, 0.07) * antihelix
    t = t + 0.0045 * np.clip((rho - 0.35) / 0.3, 0.0, 1.0) * _bump(rho, 0.85, 0.25) * lobe
    t = t + 0.0070 * _bump(rho, 0.62, 0.14) * tragus
    return t


def back_offset(u: np.ndarray) -> np.ndarray:
    """Outward offset (m) of the back face: the rear of the pinna stands off the head
    (auriculocephalic angle about 25 deg), the front is flush with it."""
    return -0.003 + 0.45 * np.clip(-(u + 0.004), 0.0, None)


def pinna_mesh(side: str) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (V, 3) and triangles (F, 3) of the left or right pinna, outward normals."""
    theta = np.linspace(0.0, 2.0 * np.pi, N_THETA, endpoint=False)
    rho = np.linspace(0.0, 1.0, N_RING + 1)[1:]
    r_out = outline(theta)
    rr, tt = np.meshgrid(rho, theta, indexing="ij")  # (N_RING, N_THETA)
    u = rr * r_out[None, :] * np.cos(tt)
    v = rr * r_out[None, :] * np.sin(tt)
    w_back = back_offset(u)
    w_top = w_back + relief(rr, tt)
    sign = 1.0 if side == "left" else -1.0

    def pts(w):
        return np.stack([u, sign * w, v], axis=-1).reshape(-1, 3)

    c_back = np.array([0.0, sign * back_offset(np.array(0.0)), 0.0])
    c_top = np.array([0.0, sign * (back_offset(np.array(0.0)) + relief(np.array(0.0), np.array(0.0))), 0.0])
    top = pts(w_top)
    back = pts(w_back)
    n_ring_pts = N_RING * N_THETA
    verts = np.vstack([c_top, top, c_back, back])
    i_ct, top0, i_cb, back0 = 0, 1, 1 + n_ring_pts, 2 + n_ring_pts

    def idx(base, ring, k):
        return base + ring * N_THETA + (k % N_THETA)

    faces = []
    for k in range(N_THETA):
        # Fans around the centres (top face outward along +w, back face along -w).
        faces.append((i_ct, idx(top0, 0, k), idx(top0, 0, k + 1)))
        faces.append((i_cb, idx(back0, 0, k + 1), idx(back0, 0, k)))
        for ring in range(N_RING - 1):
            a, b = idx(top0, ring, k), idx(top0, ring, k + 1)
            c, d = idx(top0, ring + 1, k + 1), idx(top0, ring + 1, k)
            faces += [(a, d, c), (a, c, b)]
            a, b = idx(back0, ring, k), idx(back0, ring, k + 1)
            c, d = idx(back0, ring + 1, k + 1), idx(back0, ring + 1, k)
            faces += [(a, c, d), (a, b, c)]
        # Side wall joining the outer rings.
        a, b = idx(top0, N_RING - 1, k), idx(top0, N_RING - 1, k + 1)
        c, d = idx(back0, N_RING - 1, k + 1), idx(back0, N_RING - 1, k)
        faces += [(a, d, c), (a, c, b)]
    faces = np.array(faces, dtype=np.int64)
    # The triangles above are counter-clockwise seen from outside in (u, v, w) coordinates.
    # Mapping them to (x, y, z) = (u, w, v) swaps two axes, which reverses the winding: flip
    # the left ear back. The right ear's mirror (y = -w) swaps it once more, so it stays.
    if side == "left":
        faces = faces[:, ::-1]
    return verts, faces


def signed_volume(verts: np.ndarray, faces: np.ndarray) -> float:
    """Volume (m^3) enclosed by a triangle mesh; positive when normals point outward."""
    a, b, c = verts[faces[:, 0]], verts[faces[:, 1]], verts[faces[:, 2]]
    return float(np.sum(np.einsum("ij,ij->i", a, np.cross(b, c))) / 6.0)


def write_stl(path: Path, verts: np.ndarray, faces: np.ndarray, name: str) -> None:
    """Binary STL (little-endian, float32), with per-face normals."""
    tri = verts[faces].astype(np.float32)
    normals = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    header = f"acoustic-sim {name}".encode().ljust(80, b" ")
    with open(path, "wb") as f:
        f.write(header)
        f.write(struct.pack("<I", len(faces)))
        rec = np.zeros(len(faces), dtype=[("n", "<f4", 3), ("v", "<f4", (3, 3)), ("attr", "<u2")])
        rec["n"] = normals
        rec["v"] = tri
        f.write(rec.tobytes())


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--out", type=Path, default=Path(__file__).resolve().parent / "assets",
                        help="output folder (default: assets/musashi_head/assets)")
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    for side in ("left", "right"):
        verts, faces = pinna_mesh(side)
        vol = signed_volume(verts, faces)
        if vol <= 0:
            raise RuntimeError(f"pinna_{side}: inward normals (volume {vol:.3e} m^3)")
        path = args.out / f"pinna_{side}.stl"
        write_stl(path, verts, faces, f"pinna_{side}")
        print(f"{path}: {len(faces)} triangles, volume {vol * 1e6:.2f} cm^3")


if __name__ == "__main__":
    main()
