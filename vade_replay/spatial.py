"""Poses and rotations on plain Python floats.

Quaternions are (x, y, z, w) tuples of unit length. Transcendentals go through ``math``
on scalars, never numpy's SIMD kernels, so results are bit-identical on a given machine
(the determinism contract in the README). One part's step is a few hundred of these
operations; plain floats are several times faster than numpy scalars for that.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

Vec3 = tuple[float, float, float]
Quat = tuple[float, float, float, float]
Mat3 = tuple[Vec3, Vec3, Vec3]

# (Not Final: mypyc 2.4 compiles a Final tuple of floats read anywhere to "value for final
# name ... was not set".)
IDENTITY_QUAT: Quat = (0.0, 0.0, 0.0, 1.0)
ZERO3: Vec3 = (0.0, 0.0, 0.0)


def add(a: Vec3, b: Vec3) -> Vec3:
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2])


def sub(a: Vec3, b: Vec3) -> Vec3:
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


def scale(a: Vec3, s: float) -> Vec3:
    return (a[0] * s, a[1] * s, a[2] * s)


def dot(a: Vec3, b: Vec3) -> float:
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def cross(a: Vec3, b: Vec3) -> Vec3:
    return (
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    )


def norm(a: Vec3) -> float:
    return math.sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2])


def normalize(a: Vec3) -> Vec3:
    n = norm(a)
    if n == 0.0:
        raise ValueError("cannot normalise a zero vector")
    return (a[0] / n, a[1] / n, a[2] / n)


def quat_mul(a: Quat, b: Quat) -> Quat:
    """Hamilton product a * b (apply b first, then a)."""
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return (
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
        aw * bw - ax * bx - ay * by - az * bz,
    )


def quat_conj(q: Quat) -> Quat:
    return (-q[0], -q[1], -q[2], q[3])


def quat_normalize(q: Quat) -> Quat:
    n = math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
    # (Compiled, isinf and isnan are C calls; math.isfinite, no mypyc primitive, a Python
    # call on a boxed float: this runs for every pose composed.)
    if n == 0.0 or math.isinf(n) or math.isnan(n):
        raise ValueError(f"not a rotation quaternion: {q}")
    # One sign for each rotation keeps recorded values canonical.
    if q[3] < 0.0:
        n = -n
    return (q[0] / n, q[1] / n, q[2] / n, q[3] / n)


def quat_rotate(q: Quat, v: Vec3) -> Vec3:
    """Rotate v by unit quaternion q."""
    qx, qy, qz, qw = q
    # t = 2 (q_vec x v); v' = v + w t + q_vec x t
    tx = 2.0 * (qy * v[2] - qz * v[1])
    ty = 2.0 * (qz * v[0] - qx * v[2])
    tz = 2.0 * (qx * v[1] - qy * v[0])
    return (
        v[0] + qw * tx + (qy * tz - qz * ty),
        v[1] + qw * ty + (qz * tx - qx * tz),
        v[2] + qw * tz + (qx * ty - qy * tx),
    )


def quat_from_rotvec(r: Vec3) -> Quat:
    """exp: rotation vector (axis * angle, radians) to quaternion."""
    angle = norm(r)
    if angle < 1e-8:
        # Taylor series: sin(a/2)/a = 1/2 - a^2/48 + ...
        k = 0.5 - angle * angle / 48.0
        return quat_normalize((r[0] * k, r[1] * k, r[2] * k, 1.0 - angle * angle / 8.0))
    half = 0.5 * angle
    k = math.sin(half) / angle
    return (r[0] * k, r[1] * k, r[2] * k, math.cos(half))


def quat_to_rotvec(q: Quat) -> Vec3:
    """log: quaternion to rotation vector with angle in [0, pi]."""
    x, y, z, w = q
    if w < 0.0:
        x, y, z, w = -x, -y, -z, -w
    s = math.sqrt(x * x + y * y + z * z)
    if s < 1e-12:
        k = 2.0 / w if w != 0.0 else 0.0
        return (x * k, y * k, z * k)
    angle = 2.0 * math.atan2(s, w)
    k = angle / s
    return (x * k, y * k, z * k)


def quat_angle_between(a: Quat, b: Quat) -> float:
    """Angle in radians of the rotation that takes a to b."""
    return norm(quat_to_rotvec(quat_mul(b, quat_conj(a))))


def quat_axis_angle(axis: Vec3, angle: float) -> Quat:
    return quat_unit_axis_angle(normalize(axis), angle)


def quat_unit_axis_angle(u: Vec3, angle: float) -> Quat:
    """``quat_axis_angle`` for an axis already normalised (``normalize(axis)``, which a
    caller can compute once): the same bits, without the square root and divisions."""
    s = math.sin(0.5 * angle)
    return (u[0] * s, u[1] * s, u[2] * s, math.cos(0.5 * angle))


def quat_to_matrix(q: Quat) -> Mat3:
    x, y, z, w = q
    return (
        (1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)),
        (2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)),
        (2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)),
    )


def quat_from_matrix(m) -> Quat:
    """Rotation matrix (any 3x3 indexable) to unit quaternion (Shepperd's method)."""
    m00, m01, m02 = float(m[0][0]), float(m[0][1]), float(m[0][2])
    m10, m11, m12 = float(m[1][0]), float(m[1][1]), float(m[1][2])
    m20, m21, m22 = float(m[2][0]), float(m[2][1]), float(m[2][2])
    tr = m00 + m11 + m22
    if tr > 0.0:
        s = math.sqrt(tr + 1.0) * 2.0
        q = ((m21 - m12) / s, (m02 - m20) / s, (m10 - m01) / s, 0.25 * s)
    elif m00 > m11 and m00 > m22:
        s = math.sqrt(1.0 + m00 - m11 - m22) * 2.0
        q = (0.25 * s, (m01 + m10) / s, (m02 + m20) / s, (m21 - m12) / s)
    elif m11 > m22:
        s = math.sqrt(1.0 + m11 - m00 - m22) * 2.0
        q = ((m01 + m10) / s, 0.25 * s, (m12 + m21) / s, (m02 - m20) / s)
    else:
        s = math.sqrt(1.0 + m22 - m00 - m11) * 2.0
        q = ((m02 + m20) / s, (m12 + m21) / s, 0.25 * s, (m10 - m01) / s)
    return quat_normalize(q)


def quat_from_euler_deg(roll: float, pitch: float, yaw: float) -> Quat:
    """Extrinsic x-y-z (roll about x, then pitch about y, then yaw about z), degrees."""
    qx = quat_axis_angle((1.0, 0.0, 0.0), math.radians(roll))
    qy = quat_axis_angle((0.0, 1.0, 0.0), math.radians(pitch))
    qz = quat_axis_angle((0.0, 0.0, 1.0), math.radians(yaw))
    return quat_normalize(quat_mul(qz, quat_mul(qy, qx)))


def slerp(a: Quat, b: Quat, t: float) -> Quat:
    """Constant-angular-velocity interpolation from a (t=0) to b (t=1)."""
    rel = quat_mul(b, quat_conj(a))
    return quat_normalize(quat_mul(quat_from_rotvec(scale(quat_to_rotvec(rel), t)), a))


def mat_vec(m: Mat3, v: Vec3) -> Vec3:
    return (dot(m[0], v), dot(m[1], v), dot(m[2], v))


def mat_mul(a: Mat3, b: Mat3) -> Mat3:
    bt = transpose(b)
    return tuple(tuple(dot(row, col) for col in bt) for row in a)  # type: ignore[return-value]


def transpose(m: Mat3) -> Mat3:
    return ((m[0][0], m[1][0], m[2][0]), (m[0][1], m[1][1], m[2][1]), (m[0][2], m[1][2], m[2][2]))


# Jacobi sweeps: a 3x3 converges in about five; this only bounds a matrix of NaNs.
_JACOBI_SWEEPS = 64


def symmetric_eigen(m) -> tuple[Vec3, Mat3]:
    """Eigenvalues, ascending, and eigenvectors (the columns, a rotation: determinant +1) of
    a symmetric 3x3 matrix (its upper triangle is read), by cyclic Jacobi rotations.

    Only +, -, *, / and sqrt, each rounded as IEEE 754 requires, in a fixed order: the same
    bits on every machine (compiled, with no fused multiply-adds: setup.py's
    ``-ffp-contract=off``). numpy's ``eigh`` goes through LAPACK and BLAS, whose kernels are
    chosen by the CPU: two machines of one kind gave a cylinder different principal axes
    (its two equal moments leave them free) and every part's axes different round-off."""
    a = [[float(m[0][0]), float(m[0][1]), float(m[0][2])],
         [float(m[0][1]), float(m[1][1]), float(m[1][2])],
         [float(m[0][2]), float(m[1][2]), float(m[2][2])]]
    v = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
    for _ in range(_JACOBI_SWEEPS):
        rotated = False
        for p, q, r in ((0, 1, 2), (0, 2, 1), (1, 2, 0)):
            apq = a[p][q]
            if apq == 0.0:
                continue
            app, aqq = a[p][p], a[q][q]
            # Below the diagonal's last bit: the rotation would change nothing (Numerical
            # Recipes' test), and setting it to zero ends the sweeps.
            g = 100.0 * abs(apq)
            if abs(app) + g == abs(app) and abs(aqq) + g == abs(aqq):
                a[p][q] = a[q][p] = 0.0
                continue
            rotated = True
            theta = (aqq - app) / (2.0 * apq)
            if abs(theta) > 1e150:  # theta^2 would overflow: t ~ 1 / (2 theta)
                t = 0.5 / theta
            else:
                t = 1.0 / (abs(theta) + math.sqrt(theta * theta + 1.0))
                if theta < 0.0:
                    t = -t
            c = 1.0 / math.sqrt(t * t + 1.0)
            s = t * c
            tau = s / (1.0 + c)
            h = t * apq
            a[p][p] = app - h
            a[q][q] = aqq + h
            a[p][q] = a[q][p] = 0.0
            arp, arq = a[r][p], a[r][q]
            a[r][p] = a[p][r] = arp - s * (arq + tau * arp)
            a[r][q] = a[q][r] = arq + s * (arp - tau * arq)
            for row in v:
                vp, vq = row[p], row[q]
                row[p] = vp - s * (vq + tau * vp)
                row[q] = vq + s * (vp - tau * vq)
        if not rotated:
            break
    # Ascending, ties in index order; a reflection is turned into a rotation.
    order = sorted(range(3), key=lambda i: (a[i][i], i))
    values = (a[order[0]][order[0]], a[order[1]][order[1]], a[order[2]][order[2]])
    cols = [(v[0][i], v[1][i], v[2][i]) for i in order]
    if dot(cross(cols[0], cols[1]), cols[2]) < 0.0:
        cols[2] = scale(cols[2], -1.0)
    return values, transpose((cols[0], cols[1], cols[2]))


@dataclass(slots=True)
class Pose:
    """A rigid transform ``a_from_b``: maps coordinates in frame b to frame a.

    A value: never changed after it is made (see ``frames`` for why it is not frozen)."""

    position: Vec3
    rotation: Quat

    def __init__(self, position: Vec3 = ZERO3, rotation: Quat = IDENTITY_QUAT) -> None:
        self.position = position
        self.rotation = rotation

    def apply(self, v: Vec3) -> Vec3:
        return add(quat_rotate(self.rotation, v), self.position)

    def compose(self, other: "Pose") -> "Pose":
        """self * other: ``a_from_b.compose(b_from_c)`` is ``a_from_c``."""
        return Pose(
            add(quat_rotate(self.rotation, other.position), self.position),
            quat_normalize(quat_mul(self.rotation, other.rotation)),
        )

    def inverse(self) -> "Pose":
        inv = quat_conj(self.rotation)
        return Pose(scale(quat_rotate(inv, self.position), -1.0), inv)


IDENTITY = Pose()
