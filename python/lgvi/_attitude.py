"""Attitude helpers on arrays (numpy only): rotation matrices of scalar-first
quaternions, Euler angles of any sequence, and roll/pitch/yaw in the LVLH
frame of a body's orbit about the origin (the central source).

The LVLH frame (as for the scenario key ``[initial] attitude``): x radial
(from the centre out, x / |x|), z the orbit normal (x cross p) / |x cross p|,
y = z cross x (along-track: the velocity's direction on a circular orbit).
The body's attitude in it, A = R_LVLH^T R, is Rz(pitch) Ry(roll) Rx(yaw):
pitch about the orbit normal first, then roll about the new y, then yaw about
the new x (the intrinsic sequence "ZYX" of euler_angles, returned in the order
roll, pitch, yaw).
"""

import numpy as np

_AXES = {"x": 0, "y": 1, "z": 2}


def rotation_matrices(q):
    """R = pi(q) for scalar-first quaternions: (4,) -> (3, 3), (..., 4) -> (..., 3, 3).

    pi(q) = (2 qw^2 - 1) I + 2 v v^T + 2 qw hat(v), v = (qx, qy, qz): the
    paper's map, as the C++ library evaluates it (S3::matrix), so that
    for a q whose norm is 1 only to round-off (an integrator's state) Python
    and C++ give the same matrix to round-off, not to |q|^2 - 1.
    """
    q = np.asarray(q, dtype=float)
    w, v = q[..., 0], q[..., 1:]
    hat = np.zeros(q.shape[:-1] + (3, 3))
    hat[..., 0, 1], hat[..., 0, 2] = -v[..., 2], v[..., 1]
    hat[..., 1, 0], hat[..., 1, 2] = v[..., 2], -v[..., 0]
    hat[..., 2, 0], hat[..., 2, 1] = -v[..., 1], v[..., 0]
    return ((2.0 * w * w - 1.0)[..., None, None] * np.eye(3)
            + 2.0 * v[..., :, None] * v[..., None, :]
            + 2.0 * w[..., None, None] * hat)


def euler_angles(R, seq="ZYX", degrees=False):
    """Euler angles (a, b, c) of rotation matrices R (..., 3, 3) for a sequence of three axes.

    Upper case: intrinsic, R = R_A(a) R_B(b) R_C(c) for seq "ABC" (each turn
    about the axis already turned); lower case: extrinsic (about the fixed
    axes, first a about A), R = R_C(c) R_B(b) R_A(a) (scipy's convention).
    Tait-Bryan sequences (three different axes, e.g. "ZYX") give b in
    [-90, 90] deg; proper sequences (first = last, e.g. "ZXZ") give b in
    [0, 180] deg. At the singular middle angle (b = +-90 deg, resp. 0 or 180
    deg) the split between a and c is arbitrary.
    """
    if not isinstance(seq, str) or len(seq) != 3 or not (seq.isupper() or seq.islower()) \
            or any(ch not in _AXES for ch in seq.lower()) or seq[0].lower() == seq[1].lower() \
            or seq[1].lower() == seq[2].lower():
        raise ValueError(f"seq: {seq!r} must be three axes from x, y, z, consecutive ones different, all upper "
                         "case (intrinsic, e.g. 'ZYX') or all lower case (extrinsic, e.g. 'xyz')")
    R = np.asarray(R, dtype=float)
    if R.shape[-2:] != (3, 3):
        raise ValueError(f"R: must have shape (..., 3, 3), got {R.shape}")
    extrinsic = seq.islower()
    # Extrinsic "abc" is intrinsic "CBA" with the angles reversed.
    axes = [_AXES[ch] for ch in (seq[::-1] if extrinsic else seq).lower()]
    i, j, k = axes
    if i != k:  # Tait-Bryan: R = R_i(a) R_j(b) R_k(c)
        s = 1.0 if (j - i) % 3 == 1 else -1.0  # +1 for a cyclic (i, j, k)
        b = np.arcsin(np.clip(s * R[..., i, k], -1.0, 1.0))
        a = np.arctan2(-s * R[..., j, k], R[..., k, k])
        c = np.arctan2(-s * R[..., i, j], R[..., i, i])
    else:  # proper Euler: R = R_i(a) R_j(b) R_i(c), m the third axis
        m = 3 - i - j
        s = 1.0 if (j - i) % 3 == 1 else -1.0
        b = np.arccos(np.clip(R[..., i, i], -1.0, 1.0))
        a = np.arctan2(R[..., j, i], -s * R[..., m, i])
        c = np.arctan2(R[..., i, j], s * R[..., i, m])
    out = np.stack([c, b, a] if extrinsic else [a, b, c], -1)
    return np.degrees(out) if degrees else out


def lvlh_frames(x, p):
    """LVLH axes as the columns of (N, 3, 3) matrices, from positions x and momenta (or velocities) p (N, 3)."""
    x = np.asarray(x, dtype=float)
    p = np.asarray(p, dtype=float)
    h = np.cross(x, p)
    hn = np.linalg.norm(h, axis=-1)
    if np.any(hn == 0.0):
        raise ValueError("lvlh: the LVLH frame needs an orbit about the origin; at some row the position and "
                         "momentum are parallel or zero")
    ex = x / np.linalg.norm(x, axis=-1)[..., None]
    ez = h / hn[..., None]
    ey = np.cross(ez, ex)
    return np.stack([ex, ey, ez], -1)


def lvlh_angles(x, p, q, degrees=True):
    """(N, 3) roll, pitch, yaw of the body in the LVLH frame of its orbit about the origin (see the module doc)."""
    A = np.swapaxes(lvlh_frames(x, p), -1, -2) @ rotation_matrices(q)
    pitch_roll_yaw = euler_angles(A, "ZYX", degrees=degrees)
    return pitch_roll_yaw[..., [1, 0, 2]]
