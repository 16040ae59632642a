"""Compiled kernels (numba) for the decode tail and the end-to-end error check.

The error check decodes a clip some tens of times while its coding is searched, so the
numpy decode (`representations.positions.decode_markers`, `solve_local`, `Aligned.inverse`,
`kinematics.inverse`, `rotations.euler_angles`), the AMC rounding, forward kinematics
and the joint distances are also written here as loops over frames and joints. Each
kernel mirrors one numpy function in its order of operations (scores agree to about
1e-13 cm); `tests/test_compiled_decode.py` holds them to the numpy code.

The kernels take plain arrays: `representations.weighted.ChannelTables` prepares a skeleton's
channel layout for them, and `representations.positions.MarkerDecoder` a marker
representation's columns. All helpers live in this one file because numba's cache does not
notice edits to helpers in other files. Compiled code is cached next to this file (or in
numba's user cache): only the first run on a machine compiles, about 15 s.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

PI = np.pi
TWO_PI = 2 * np.pi  # np.unwrap's default period, and rotations.wrap's modulus
GIMBAL = 1e-9  # rotations._GIMBAL
TWO_DOF_ROUNDS = 20  # rotations._TWO_DOF_ROUNDS
TWO_DOF_TOLERANCE = 1e-13  # rotations._TWO_DOF_TOLERANCE
POW10 = np.power(10.0, np.arange(-300, 301).astype(np.float64))  # as round_as_written's 10.0 ** array


# ----------------------------------------------------------------------------- scalar helpers

@njit(cache=True, nogil=True)
def _npmod(a, b):
    """numpy's float remainder (npy_divmod): fmod, moved to the sign of b."""
    m = np.fmod(a, b)
    if m != 0.0:
        if (b < 0.0) != (m < 0.0):
            m += b
    else:
        m = math.copysign(0.0, b)
    return m


@njit(cache=True, nogil=True)
def _mod2pi(y):
    """numpy's y % (2 pi), bit for bit: fmod is exact, so within one period either side of
    [0, 2 pi) the result is y, y + 2 pi or y - 2 pi (exact by Sterbenz) without calling fmod."""
    if y >= 0.0:
        if y < TWO_PI:
            return y + 0.0  # -0.0 -> +0.0, as npy_divmod's copysign(0, b)
        if y < 2.0 * TWO_PI:
            return y - TWO_PI
    elif y >= -TWO_PI:
        return y + TWO_PI
    return _npmod(y, TWO_PI)


@njit(cache=True, nogil=True)
def _wrap(x):
    """rotations.wrap: (x + pi) % (2 pi) - pi."""
    return _mod2pi(x + PI) - PI


@njit(cache=True, nogil=True)
def _axis_rot(k, angle, out):
    """rotations.axis_rotation (row convention) into out (3, 3)."""
    b = (k + 1) % 3
    c = (k + 2) % 3
    co = math.cos(angle)
    si = math.sin(angle)
    for i in range(3):
        for l in range(3):
            out[i, l] = 0.0
    out[k, k] = 1.0
    out[b, b] = co
    out[c, c] = co
    out[b, c] = si
    out[c, b] = -si


@njit(cache=True, nogil=True)
def _load(stack, i, out):
    """out = stack[i] (3x3), copied element by element: `stack[i]` would make a view, and numba
    counts each view's references with atomic operations, which cost markers_to_channels a fifth of
    its time when it made one per joint and frame."""
    for r in range(3):
        for k in range(3):
            out[r, k] = stack[i, r, k]


@njit(cache=True, nogil=True)
def _store(m, stack, i):
    """stack[i] = m (3x3), without a view (`_load`)."""
    for r in range(3):
        for k in range(3):
            stack[i, r, k] = m[r, k]


@njit(cache=True, nogil=True)
def _mm(a, b, out):
    """out = a @ b (3x3), sums in index order."""
    for i in range(3):
        a0 = a[i, 0]
        a1 = a[i, 1]
        a2 = a[i, 2]
        for k in range(3):
            out[i, k] = a0 * b[0, k] + a1 * b[1, k] + a2 * b[2, k]


@njit(cache=True, nogil=True)
def _mtm(a, b, out):
    """out = a^T @ b (3x3)."""
    for i in range(3):
        a0 = a[0, i]
        a1 = a[1, i]
        a2 = a[2, i]
        for k in range(3):
            out[i, k] = a0 * b[0, k] + a1 * b[1, k] + a2 * b[2, k]


@njit(cache=True, nogil=True)
def _mmt(a, b, out):
    """out = a @ b^T (3x3)."""
    for i in range(3):
        a0 = a[i, 0]
        a1 = a[i, 1]
        a2 = a[i, 2]
        for k in range(3):
            out[i, k] = a0 * b[k, 0] + a1 * b[k, 1] + a2 * b[k, 2]


@njit(cache=True, nogil=True)
def _angle_about_m(k, m):
    """rotations.angle_about for one matrix."""
    b = (k + 1) % 3
    c = (k + 2) % 3
    return math.atan2(m[b, c] - m[c, b], m[b, b] + m[c, c])


@njit(cache=True, nogil=True)
def _unwrap_inplace(p):
    """np.unwrap (period 2 pi, discont pi) of a 1-D array, in place."""
    n = p.shape[0]
    cum = 0.0
    prev = p[0] if n > 0 else 0.0
    for i in range(1, n):
        cur = p[i]
        dd = cur - prev
        ddmod = _mod2pi(dd + PI) - PI
        if ddmod == -PI and dd > 0.0:
            ddmod = PI
        ph = ddmod - dd
        if abs(dd) < PI:
            ph = 0.0
        cum += ph
        p[i] = cur + cum
        prev = cur


@njit(cache=True, nogil=True)
def _pairwise_leaf(a, lo, n):
    """numpy's pairwise_sum_DOUBLE for n <= 128 (PW_BLOCKSIZE)."""
    if n < 8:
        res = 0.0
        for i in range(n):
            res += a[lo + i]
        return res
    r0 = a[lo]
    r1 = a[lo + 1]
    r2 = a[lo + 2]
    r3 = a[lo + 3]
    r4 = a[lo + 4]
    r5 = a[lo + 5]
    r6 = a[lo + 6]
    r7 = a[lo + 7]
    i = 8
    end = n - (n % 8)
    while i < end:
        r0 += a[lo + i]
        r1 += a[lo + i + 1]
        r2 += a[lo + i + 2]
        r3 += a[lo + i + 3]
        r4 += a[lo + i + 4]
        r5 += a[lo + i + 5]
        r6 += a[lo + i + 6]
        r7 += a[lo + i + 7]
        i += 8
    res = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
    while i < n:
        res += a[lo + i]
        i += 1
    return res


@njit(cache=True, nogil=True)
def _pairwise_sum(a, lo, n):
    """numpy's pairwise_sum_DOUBLE over a[lo:lo+n], its recursion unrolled onto a stack
    (recursive njit functions crash when loaded from numba's cache)."""
    if n <= 128:
        return _pairwise_leaf(a, lo, n)
    s_lo = np.empty(128, np.int64)
    s_n = np.empty(128, np.int64)
    s_state = np.empty(128, np.int64)
    vals = np.empty(128)
    sp = 0
    vp = 0
    s_lo[0] = lo
    s_n[0] = n
    s_state[0] = 0
    sp = 1
    while sp > 0:
        top = sp - 1
        tlo = s_lo[top]
        tn = s_n[top]
        if tn <= 128:
            sp -= 1
            vals[vp] = _pairwise_leaf(a, tlo, tn)
            vp += 1
            continue
        n2 = tn // 2
        n2 -= n2 % 8
        st = s_state[top]
        if st == 0:
            s_state[top] = 1
            s_lo[sp] = tlo
            s_n[sp] = n2
            s_state[sp] = 0
            sp += 1
        elif st == 1:
            s_state[top] = 2
            s_lo[sp] = tlo + n2
            s_n[sp] = tn - n2
            s_state[sp] = 0
            sp += 1
        else:
            sp -= 1
            right = vals[vp - 1]
            left = vals[vp - 2]
            vp -= 2
            vals[vp] = left + right
            vp += 1
    return vals[0]


@njit(cache=True, nogil=True)
def np_sum(a):
    """np.sum of a contiguous 1-D float64 array (add.reduce: pairwise summation), bit for bit
    as `tests/test_compiled_decode.py` checks."""
    return _pairwise_sum(a, 0, a.shape[0])


# ----------------------------------------------------------------------------- euler fits

@njit(cache=True, nogil=True)
def _angle_about_product(k, ra, rb, m):
    """_angle_about_m(k, (ra @ rb)^T @ m), of the four entries it reads only, each summed as _mm and _mtm sum it."""
    b = (k + 1) % 3
    c = (k + 2) % 3
    pb0 = ra[0, 0] * rb[0, b] + ra[0, 1] * rb[1, b] + ra[0, 2] * rb[2, b]
    pb1 = ra[1, 0] * rb[0, b] + ra[1, 1] * rb[1, b] + ra[1, 2] * rb[2, b]
    pb2 = ra[2, 0] * rb[0, b] + ra[2, 1] * rb[1, b] + ra[2, 2] * rb[2, b]
    pc0 = ra[0, 0] * rb[0, c] + ra[0, 1] * rb[1, c] + ra[0, 2] * rb[2, c]
    pc1 = ra[1, 0] * rb[0, c] + ra[1, 1] * rb[1, c] + ra[1, 2] * rb[2, c]
    pc2 = ra[2, 0] * rb[0, c] + ra[2, 1] * rb[1, c] + ra[2, 2] * rb[2, c]
    r_bc = pb0 * m[0, c] + pb1 * m[1, c] + pb2 * m[2, c]
    r_cb = pc0 * m[0, b] + pc1 * m[1, b] + pc2 * m[2, b]
    r_bb = pb0 * m[0, b] + pb1 * m[1, b] + pb2 * m[2, b]
    r_cc = pc0 * m[0, c] + pc1 * m[1, c] + pc2 * m[2, c]
    return math.atan2(r_bc - r_cb, r_bb + r_cc)


@njit(cache=True, nogil=True)
def _tait_bryan_all(locals_j, a, b, c, first, middle, last, ra, rb, m):
    """rotations._tait_bryan over frames (gimbal-locked frames carry the latest unlocked first angle)."""
    sign = 1.0 if (b - a) % 3 == 1 else -1.0
    have_free = False
    free_first = 0.0
    for f in range(locals_j.shape[0]):
        _load(locals_j, f, m)
        cos_middle = math.hypot(m[b, c], m[c, c])
        fi = math.atan2(sign * m[b, c], m[c, c])
        mi = math.atan2(-sign * m[a, c], cos_middle)
        if cos_middle < GIMBAL:
            fi = free_first if have_free else 0.0
        else:
            have_free = True
            free_first = fi
        _axis_rot(a, fi, ra)
        _axis_rot(b, mi, rb)
        first[f] = fi
        middle[f] = mi
        last[f] = _angle_about_product(c, ra, rb, m)


@njit(cache=True, nogil=True)
def _euler3(locals_j, a, b, c, out_angles, work, ra, rb, m):
    """rotations.euler_angles for 3 axes: _tait_bryan, _continuous (branch parity), np.unwrap."""
    n = locals_j.shape[0]
    first = work[0]
    middle = work[1]
    last = work[2]
    _tait_bryan_all(locals_j, a, b, c, first, middle, last, ra, rb, m)
    parity = False
    for f in range(n):
        if f > 0:
            d0 = _wrap(first[f] - first[f - 1])
            d1 = _wrap(middle[f] - middle[f - 1])
            d2 = _wrap(last[f] - last[f - 1])
            stay = d0 ** 2 + d1 ** 2 + d2 ** 2
            e0 = _wrap((first[f] + PI) - first[f - 1])
            e1 = _wrap((PI - middle[f]) - middle[f - 1])
            e2 = _wrap((last[f] + PI) - last[f - 1])
            switch = e0 ** 2 + e1 ** 2 + e2 ** 2
            if switch < stay:
                parity = not parity
        if parity:
            out_angles[0, f] = first[f] + PI
            out_angles[1, f] = PI - middle[f]
            out_angles[2, f] = last[f] + PI
        else:
            out_angles[0, f] = first[f]
            out_angles[1, f] = middle[f]
            out_angles[2, f] = last[f]
    for i in range(3):
        _unwrap_inplace(out_angles[i])


@njit(cache=True, nogil=True)
def _euler2(locals_j, a0, a1, out_angles, work, ra, rb, res, m):
    """rotations.euler_angles for 2 axes: _two_axis_fit (all frames iterate together, as the
    numpy code's global stopping test does), then np.unwrap."""
    n = locals_j.shape[0]
    missing = 3 - a0 - a1
    first = out_angles[0]
    second = out_angles[1]
    third = work[2]
    _tait_bryan_all(locals_j, a0, a1, missing, first, second, third, ra, rb, m)
    for f in range(n):
        if abs(_wrap(third[f] + PI)) < abs(_wrap(third[f])):
            first[f] = first[f] + PI
            second[f] = PI - second[f]
    for _ in range(TWO_DOF_ROUNDS):
        worst = 0.0
        nan = False
        for f in range(n):
            _load(locals_j, f, m)
            bf = first[f]
            bs = second[f]
            _axis_rot(a1, bs, rb)
            _mmt(m, rb, res)  # m @ R_a1(second)^T
            nf = _angle_about_m(a0, res)
            _axis_rot(a0, nf, ra)
            _mtm(ra, m, res)  # R_a0(first)^T @ m
            ns = _angle_about_m(a1, res)
            first[f] = nf
            second[f] = ns
            d = abs(_wrap(nf - bf))
            e = abs(_wrap(ns - bs))
            if d != d or e != e:
                nan = True
            if d > worst:
                worst = d
            if e > worst:
                worst = e
        if not nan and worst < TWO_DOF_TOLERANCE:
            break
    _unwrap_inplace(first)
    _unwrap_inplace(second)


@njit(cache=True, nogil=True)
def _euler1(locals_j, a, out_angles, m):
    for f in range(locals_j.shape[0]):
        _load(locals_j, f, m)
        out_angles[0, f] = _angle_about_m(a, m)
    _unwrap_inplace(out_angles[0])


# ----------------------------------------------------------------------------- decode tail

@njit(cache=True, nogil=True)
def _orthonormal(x0, x1, x2, y0, y1, y2, out):
    """rotations.orthonormal_frame for one (x, y) pair: rows x, y', z."""
    nx = math.sqrt(x0 * x0 + x1 * x1 + x2 * x2)
    nx = max(nx, 1e-300)
    x0 = x0 / nx
    x1 = x1 / nx
    x2 = x2 / nx
    d = y0 * x0 + y1 * x1 + y2 * x2
    y0 = y0 - d * x0
    y1 = y1 - d * x1
    y2 = y2 - d * x2
    ny = math.sqrt(y0 * y0 + y1 * y1 + y2 * y2)
    ny = max(ny, 1e-300)
    y0 = y0 / ny
    y1 = y1 / ny
    y2 = y2 / ny
    out[0, 0] = x0
    out[0, 1] = x1
    out[0, 2] = x2
    out[1, 0] = y0
    out[1, 1] = y1
    out[1, 2] = y2
    out[2, 0] = x1 * y2 - x2 * y1
    out[2, 1] = x2 * y0 - x0 * y2
    out[2, 2] = x0 * y1 - x1 * y0


@njit(cache=True, nogil=True)
def _length(x0, x1, x2):
    """np.linalg.norm of one vector along the last axis: (x0^2 + x1^2) + x2^2, as numpy sums three."""
    return math.sqrt(x0 * x0 + x1 * x1 + x2 * x2)


@njit(cache=True, nogil=True)
def _across_length(x0, x1, x2, y0, y1, y2):
    """|y less its part along x|, as `positions._across` and np.linalg.norm compute it."""
    n = max(_length(x0, x1, x2), 1e-300)
    u0 = x0 / n
    u1 = x1 / n
    u2 = x2 / n
    d = y0 * u0 + y1 * u1 + y2 * u2
    return _length(y0 - d * u0, y1 - d * u1, y2 - d * u2)


@njit(cache=True, nogil=True)
def directions_clear(poses, parents, pos_col, y_col, x_col, root_ax_col, least):
    """Whether every direction `MarkerDecoder.check_directions` measures in the unweighted poses
    (F, M) is at least `least` long (a NaN is not): its numpy code, a quarter of a clip's decode,
    then runs only to name what is not."""
    J = parents.shape[0]
    pos = np.zeros((J, 3))
    for f in range(poses.shape[0]):
        for j in range(J):
            c0 = pos_col[j]
            for k in range(3):
                pos[j, k] = 0.0 if c0 < 0 else poses[f, c0 + k]
        for j in range(1, J):
            xc = x_col[j]
            if xc >= 0:
                x0 = poses[f, xc]
                x1 = poses[f, xc + 1]
                x2 = poses[f, xc + 2]
            else:
                p = parents[j]
                x0 = pos[j, 0] - pos[p, 0]
                x1 = pos[j, 1] - pos[p, 1]
                x2 = pos[j, 2] - pos[p, 2]
            if not _length(x0, x1, x2) >= least:
                return False
            yc = y_col[j]
            if yc >= 0 and not _across_length(x0, x1, x2, poses[f, yc], poses[f, yc + 1], poses[f, yc + 2]) >= least:
                return False
        if root_ax_col >= 0:
            rc = root_ax_col
            if not _length(poses[f, rc], poses[f, rc + 1], poses[f, rc + 2]) >= least:
                return False
            if not _across_length(poses[f, rc], poses[f, rc + 1], poses[f, rc + 2],
                                  poses[f, rc + 3], poses[f, rc + 4], poses[f, rc + 5]) >= least:
                return False
    return True


@njit(cache=True, nogil=True)
def markers_to_channels(poses, weights, root, with_root,
                        parents, faux, pos_col, y_col, x_col, root_ax_col, root_proxy,
                        solved, sol_u, sol_nrot, sol_a0, sol_a1, sol_radius, sol_phase, sol_ref,
                        ref, use_ref, flips_in, axis,
                        col_start, nchan, chan_kind, chan_axis, nrot, rot_axes, rot_k,
                        cm_per_unit, from_rad, width, values, j_lo, j_hi):
    """Weighted marker poses (F, M) [+ root track (F, ROOT_TRACK_WIDTH) unless `with_root`] -> AMC
    channel values (F, width), and the twist flips of the 2-dof solved bones (NR, F): the decode
    of `positions` (`with_root`: the poses hold the root position) and of `aligned` (a root track
    of x, y, z and heading), `positions.MarkerDecoder`.

    Written into `values` (F, width): every channel but the rotations of joints outside
    [j_lo, j_hi), whose local rotations over all frames are kept for their Euler fits (72 bytes
    a joint and frame); a long clip is decoded in several calls, a range of joints each, and
    each call writes the same numbers for what they share (`MarkerDecoder.channels`)."""
    F = poses.shape[0]
    NR = flips_in.shape[0]
    J = parents.shape[0]
    flips_out = np.zeros((NR, F), dtype=np.bool_)
    locals_ = np.empty(((j_hi - j_lo) * F, 3, 3))  # joint j's local rotations at rows (j - j_lo) F on
    pos = np.zeros((J, 3))
    R = np.empty((J, 3, 3))
    W = np.empty((J, 3, 3))
    fr = np.empty((3, 3))
    t1 = np.empty((3, 3))
    t2 = np.empty((3, 3))
    t3 = np.empty((3, 3))
    sa = np.empty((3, 3))
    sb = np.empty((3, 3))
    turn = np.empty((3, 3))
    sol0 = np.empty((3, 3))
    sol1 = np.empty((3, 3))
    sa0 = np.empty((3, 3))
    sa1 = np.empty((3, 3))
    sb0 = np.empty((3, 3))
    sb1 = np.empty((3, 3))
    c_j = np.empty((3, 3))  # axis[j]
    r_p = np.empty((3, 3))  # R[parents[j]]
    m = np.empty((3, 3))
    for f in range(F):
        # positions as stored (root zero without root)
        for j in range(J):
            c0 = pos_col[j]
            if c0 < 0:
                pos[j, 0] = 0.0
                pos[j, 1] = 0.0
                pos[j, 2] = 0.0
            else:
                for k in range(3):
                    pos[j, k] = poses[f, c0 + k] / weights[c0 + k]
        # stored frames: R = B^T orthonormal_frame(x, y)
        for j in range(1, J):
            if y_col[j] < 0:
                continue  # solved bone: below
            p = parents[j]
            yc = y_col[j]
            y0 = poses[f, yc] / weights[yc]
            y1 = poses[f, yc + 1] / weights[yc + 1]
            y2 = poses[f, yc + 2] / weights[yc + 2]
            xc = x_col[j]
            if xc >= 0:
                x0 = poses[f, xc] / weights[xc]
                x1 = poses[f, xc + 1] / weights[xc + 1]
                x2 = poses[f, xc + 2] / weights[xc + 2]
            else:
                x0 = pos[j, 0] - pos[p, 0]
                x1 = pos[j, 1] - pos[p, 1]
                x2 = pos[j, 2] - pos[p, 2]
            _orthonormal(x0, x1, x2, y0, y1, y2, fr)
            _load(faux, j, t1)
            _mtm(t1, fr, t2)
            _store(t2, R, j)
        if root_proxy >= 0:
            _load(R, root_proxy, t1)
        else:
            rc = root_ax_col
            _orthonormal(poses[f, rc] / weights[rc], poses[f, rc + 1] / weights[rc + 1],
                         poses[f, rc + 2] / weights[rc + 2], poses[f, rc + 3] / weights[rc + 3],
                         poses[f, rc + 4] / weights[rc + 4], poses[f, rc + 5] / weights[rc + 5], t1)
        _store(t1, R, 0)
        # solved bones, parents first (solve_local)
        for s in range(solved.shape[0]):
            j = solved[s]
            p = parents[j]
            _load(axis, j, c_j)
            b0 = pos[j, 0] - pos[p, 0]
            b1 = pos[j, 1] - pos[p, 1]
            b2 = pos[j, 2] - pos[p, 2]
            _load(R, p, r_p)
            # (bone @ R_p^T) @ C^T
            q0 = b0 * r_p[0, 0] + b1 * r_p[0, 1] + b2 * r_p[0, 2]
            q1 = b0 * r_p[1, 0] + b1 * r_p[1, 1] + b2 * r_p[1, 2]
            q2 = b0 * r_p[2, 0] + b1 * r_p[2, 1] + b2 * r_p[2, 2]
            tt0 = q0 * c_j[0, 0] + q1 * c_j[0, 1] + q2 * c_j[0, 2]
            tt1 = q0 * c_j[1, 0] + q1 * c_j[1, 1] + q2 * c_j[1, 2]
            tt2 = q0 * c_j[2, 0] + q1 * c_j[2, 1] + q2 * c_j[2, 2]
            nt = max(math.sqrt(tt0 * tt0 + tt1 * tt1 + tt2 * tt2), 1e-300)
            tv = (tt0 / nt, tt1 / nt, tt2 / nt)
            u0 = sol_u[j, 0]
            u1 = sol_u[j, 1]
            u2 = sol_u[j, 2]
            nr = sol_nrot[j]
            if nr == 0:
                for i in range(3):
                    for k in range(3):
                        t3[i, k] = 1.0 if i == k else 0.0
            elif nr == 1:
                a = sol_a0[j]
                bb = (a + 1) % 3
                cc = (a + 2) % 3
                _axis_rot(a, math.atan2(tv[cc], tv[bb]) - sol_phase[j], t3)  # sol_phase: arctan2(u_c, u_b), constant
            else:
                a = sol_a0[j]
                a2 = sol_a1[j]
                bb = (a + 1) % 3
                cc = (a + 2) % 3
                radius = sol_radius[j]
                phase = sol_phase[j]
                if a2 == bb:
                    turn0 = math.acos(min(max(tv[bb] / radius, -1.0), 1.0))
                    turn1 = -turn0
                else:
                    turn0 = math.asin(min(max(tv[cc] / radius, -1.0), 1.0))
                    turn1 = PI - turn0
                b2_ = (a2 + 1) % 3
                c2_ = (a2 + 2) % 3
                s0 = _wrap(turn0 - phase)
                _axis_rot(a, s0, sa0)
                v_b = u0 * sa0[0, b2_] + u1 * sa0[1, b2_] + u2 * sa0[2, b2_]
                v_c = u0 * sa0[0, c2_] + u1 * sa0[1, c2_] + u2 * sa0[2, c2_]
                at = math.atan2(tv[c2_], tv[b2_])
                r0 = _wrap(at - math.atan2(v_c, v_b))
                s1 = _wrap(turn1 - phase)
                _axis_rot(a, s1, sa1)
                v_b = u0 * sa1[0, b2_] + u1 * sa1[1, b2_] + u2 * sa1[2, b2_]
                v_c = u0 * sa1[0, c2_] + u1 * sa1[1, c2_] + u2 * sa1[2, c2_]
                r1 = _wrap(at - math.atan2(v_c, v_b))
                other = max(abs(s1), abs(r1)) < max(abs(s0), abs(r0))
                ri = sol_ref[j]
                if use_ref:
                    _axis_rot(a2, r0, sb0)
                    _axis_rot(a2, r1, sb1)
                    _mm(sa0, sb0, sol0)
                    _mm(sa1, sb1, sol1)
                    n0 = 0.0
                    n1 = 0.0
                    for i in range(3):
                        for k in range(3):
                            n0 += sol0[i, k] * ref[f, ri, i, k]
                            n1 += sol1[i, k] * ref[f, ri, i, k]
                    chosen = n1 > n0
                    flips_out[ri, f] = chosen != other
                    other = chosen
                    for i in range(3):
                        for k in range(3):
                            t3[i, k] = sol1[i, k] if other else sol0[i, k]
                else:
                    if ri >= 0:
                        other = other != flips_in[ri, f]
                        flips_out[ri, f] = flips_in[ri, f]
                    if other:
                        _axis_rot(a2, r1, sb1)
                        _mm(sa1, sb1, t3)
                    else:
                        _axis_rot(a2, r0, sb0)
                        _mm(sa0, sb0, t3)
            # R_j = ((C^T @ local) @ C) @ R_p
            _mtm(c_j, t3, t1)
            _mm(t1, c_j, t2)
            _mm(t2, r_p, t1)
            _store(t1, R, j)
        # world rotations: aligned family turns by the heading
        if not with_root:
            _axis_rot(1, root[f, 3], turn)
            for j in range(J):
                _load(R, j, t1)
                _mm(t1, turn, t2)
                _store(t2, W, j)
            rx = root[f, 0]
            ry = root[f, 1]
            rz = root[f, 2]
        else:
            for j in range(J):
                _load(R, j, t1)
                _store(t1, W, j)
            rx = pos[0, 0]
            ry = pos[0, 1]
            rz = pos[0, 2]
        # kinematics.inverse: M = (R_j^T C^T)^T (R_p^T C^T); translations
        for j in range(J):
            cs = col_start[j]
            if cs < 0:
                continue
            _load(axis, j, c_j)
            if nrot[j] > 0:
                # bone_frame_t = R_j^T @ C^T
                for i in range(3):
                    for k in range(3):
                        t1[i, k] = W[j, 0, i] * c_j[k, 0] + W[j, 1, i] * c_j[k, 1] + W[j, 2, i] * c_j[k, 2]
                p = parents[j]
                if j_lo <= j < j_hi:
                    row = (j - j_lo) * F + f
                    if p < 0:
                        # t1^T @ C^T
                        for i in range(3):
                            for k in range(3):
                                locals_[row, i, k] = (t1[0, i] * c_j[k, 0] + t1[1, i] * c_j[k, 1]
                                                      + t1[2, i] * c_j[k, 2])
                    else:
                        for i in range(3):
                            for k in range(3):
                                t2[i, k] = (W[p, 0, i] * c_j[k, 0] + W[p, 1, i] * c_j[k, 1]
                                            + W[p, 2, i] * c_j[k, 2])
                        _mtm(t1, t2, t3)
                        _store(t3, locals_, row)
            for k in range(nchan[j]):
                if chan_kind[j, k] == 1:
                    ax = chan_axis[j, k]
                    v = rx if ax == 0 else (ry if ax == 1 else rz)
                    values[f, cs + k] = v / cm_per_unit
    # euler fits per joint, over the frames given (continuity depends on them)
    angles = np.empty((3, F))
    work = np.empty((3, F))
    for j in range(j_lo, j_hi):
        cs = col_start[j]
        n = nrot[j]
        if cs < 0 or n == 0:
            continue
        lj = locals_[(j - j_lo) * F:(j - j_lo + 1) * F]
        if n == 3:
            _euler3(lj, rot_axes[j, 0], rot_axes[j, 1], rot_axes[j, 2], angles, work, sa, sb, m)
        elif n == 2:
            _euler2(lj, rot_axes[j, 0], rot_axes[j, 1], angles, work, sa, sb, t2, m)
        else:
            _euler1(lj, rot_axes[j, 0], angles, m)
        for i in range(n):
            col = cs + rot_k[j, i]
            for f in range(F):
                values[f, col] = angles[i, f] * from_rad
    return values, flips_out


# ----------------------------------------------------------------------------- rounding, FK, distances

@njit(cache=True, nogil=True)
def round_as_written(values, fixed, digits):
    """In place, what the AMC text of values reads back as: 'f' np.round(v, digits); 'g' `digits` significant digits."""
    F, C = values.shape
    if fixed:
        scale = 10.0 ** digits
        for f in range(F):
            for c in range(C):
                values[f, c] = np.rint(values[f, c] * scale) / scale
    else:
        for f in range(F):
            for c in range(C):
                v = values[f, c]
                e = math.floor(math.log10(abs(v))) if v != 0.0 else -math.inf
                if not math.isfinite(e):
                    e = 0.0
                n = (digits - 1) - e
                if n >= -300.0 and n <= 300.0:
                    scale = POW10[int(n) + 300]
                else:
                    scale = 10.0 ** n
                values[f, c] = np.rint(v * scale) / scale


@njit(cache=True, nogil=True)
def _rotate_rows(frame, ax, angle):
    """frame := Rot(ax, angle) @ frame: rows b, c of a bone frame turned about axis ax."""
    co = math.cos(angle)
    si = math.sin(angle)
    b = (ax + 1) % 3
    c = (ax + 2) % 3
    for col in range(3):
        rb = frame[b, col]
        rc = frame[c, col]
        frame[b, col] = co * rb + si * rc
        frame[c, col] = co * rc - si * rb


@njit(cache=True, nogil=True)
def _fk_frame(values, f, joints, parents, link, vct, axis0, col_start, nchan, chan_kind, chan_axis,
              to_rad, cm_per_unit, W, pos):
    """kinematics.forward for one frame: bone frames W (J, 3, 3) and positions (J, 3) of `joints`,
    in that order (parents first; a parent not among them must be made already)."""
    for j in joints:
        p = parents[j]
        if p < 0:
            for i in range(3):
                for k in range(3):
                    W[j, i, k] = axis0[i, k]
            pos[j, 0] = 0.0
            pos[j, 1] = 0.0
            pos[j, 2] = 0.0
        else:
            _mm(link[j], W[p], W[j])
        cs = col_start[j]
        if cs >= 0:
            for k in range(nchan[j] - 1, -1, -1):
                v = values[f, cs + k]
                ax = chan_axis[j, k]
                if chan_kind[j, k] == 0:
                    _rotate_rows(W[j], ax, v * to_rad)
                else:
                    pos[j, ax] = v * cm_per_unit
        if p >= 0:
            for col in range(3):
                pos[j, col] = pos[p, col] + (vct[j, 0] * W[j, 0, col] + vct[j, 1] * W[j, 1, col]
                                             + vct[j, 2] * W[j, 2, col])


@njit(cache=True, nogil=True)
def plant_feet(values, frames, feet, above, chain, dofs, weights, anchors, damping, rounds,
               parents, link, vct, axis0, col_start, nchan, chan_kind, chan_axis, to_rad, cm_per_unit):
    """In place, in each of `frames` (n,): the `dofs` (d,) rotation columns of `values` moved so
    that each of the `feet` (k,) joints with a weight (n, k) above 0 reaches its target. Held
    joints (weight 1) are solved first, alone, their targets their `anchors` (n, k, 3); then, if
    some are easing in or out (weight w below 1), all, an easing joint's target w of the way from
    where the first pass left it (or the frame's start, without one) to its anchor. So a joint
    that starts to ease in finds the leg where the held joints put it, and nothing jumps.
    `chain` (m,): the joints the dofs turn on the way to the feet, parents first, their rotation
    channels in `dofs` in that order; `above`: the chain's ancestors, parents first."""
    J = parents.shape[0]
    k = feet.shape[0]
    d = dofs.shape[0]
    m = chain.shape[0]
    W = np.empty((J, 3, 3))
    pos = np.empty((J, 3))
    row = np.empty((1, values.shape[1]))
    targets = np.empty((k, 3))
    active = np.zeros(k, dtype=np.bool_)
    start = np.empty(d)
    moves = np.zeros((m, k), dtype=np.bool_)  # chain joint q lies on the way to foot a
    for q in range(m):
        for a in range(k):
            j = feet[a]
            while j >= 0 and j != chain[q]:
                j = parents[j]
            moves[q, a] = j >= 0
    dof_of = np.full(values.shape[1], -1)  # a value column's place among the dofs
    for c in range(d):
        dof_of[dofs[c]] = c
    work = (np.empty((3, 3)), np.zeros((3 * k, d)), np.zeros(3 * k), np.empty((d, d)), np.empty(d))
    for i in range(frames.shape[0]):
        f = frames[i]
        row[0, :] = values[f, :]
        _fk_frame(row, 0, above, parents, link, vct, axis0, col_start, nchan, chan_kind, chan_axis, to_rad,
                  cm_per_unit, W, pos)
        _fk_frame(row, 0, chain, parents, link, vct, axis0, col_start, nchan, chan_kind, chan_axis, to_rad,
                  cm_per_unit, W, pos)
        for c in range(d):
            start[c] = row[0, dofs[c]]
        held = False
        easing = False
        for a in range(k):
            active[a] = weights[i, a] == 1.0
            held = held or active[a]
            easing = easing or 0.0 < weights[i, a] < 1.0
            targets[a, :] = anchors[i, a]
        if held:
            _gauss_newton(row, W, pos, targets, active, start, feet, chain, dofs, dof_of, moves, damping, rounds,
                          parents, link, vct, axis0, col_start, nchan, chan_kind, chan_axis, to_rad, cm_per_unit, work)
        if easing:
            for a in range(k):
                w = weights[i, a]
                active[a] = w > 0.0
                if 0.0 < w < 1.0:
                    for x in range(3):
                        targets[a, x] = pos[feet[a], x] + w * (anchors[i, a, x] - pos[feet[a], x])
            _gauss_newton(row, W, pos, targets, active, start, feet, chain, dofs, dof_of, moves, damping, rounds,
                          parents, link, vct, axis0, col_start, nchan, chan_kind, chan_axis, to_rad, cm_per_unit, work)
        for c in range(d):
            values[f, dofs[c]] = row[0, dofs[c]]


@njit(cache=True, nogil=True)
def _gauss_newton(row, W, pos, targets, active, start, feet, chain, dofs, dof_of, moves, damping, rounds,
                  parents, link, vct, axis0, col_start, nchan, chan_kind, chan_axis, to_rad, cm_per_unit, work):
    """`rounds` rounds of damped Gauss-Newton, in radians, on |target - position|^2 over the
    `active` feet + damping * |dof angles - start|^2, from `row`'s values (W and pos: their
    kinematics, kept up to date). A fixed number of rounds, with no test of whether a round
    helped: two decoders whose rounding differs then still agree to rounding.

    The Jacobian is exact: turning channel a of joint j by dθ turns every joint below j about the
    world axis w (row a of j's frame before that channel turns it) through j's start, the parent's
    position p: d position = w x (position - p) dθ."""
    turning, jac, resid, normal, grad = work
    k, d, m = feet.shape[0], dofs.shape[0], chain.shape[0]
    for _ in range(rounds):
        for a in range(k):
            for x in range(3):
                resid[3 * a + x] = targets[a, x] - pos[feet[a], x] if active[a] else 0.0
        for q in range(m):
            j = chain[q]
            cs = col_start[j]
            if cs < 0:
                continue
            p = parents[j]
            _mm(link[j], W[p], turning)
            for kk in range(nchan[j] - 1, -1, -1):
                if chan_kind[j, kk] != 0:
                    continue
                ax = chan_axis[j, kk]
                col = dof_of[cs + kk]
                for a in range(k):
                    if active[a] and moves[q, a]:
                        r0 = pos[feet[a], 0] - pos[p, 0]
                        r1 = pos[feet[a], 1] - pos[p, 1]
                        r2 = pos[feet[a], 2] - pos[p, 2]
                        jac[3 * a, col] = turning[ax, 1] * r2 - turning[ax, 2] * r1
                        jac[3 * a + 1, col] = turning[ax, 2] * r0 - turning[ax, 0] * r2
                        jac[3 * a + 2, col] = turning[ax, 0] * r1 - turning[ax, 1] * r0
                    else:
                        jac[3 * a, col] = 0.0
                        jac[3 * a + 1, col] = 0.0
                        jac[3 * a + 2, col] = 0.0
                _rotate_rows(turning, ax, row[0, cs + kk] * to_rad)
        for c in range(d):
            grad[c] = -damping * (row[0, dofs[c]] - start[c]) * to_rad
            for e in range(3 * k):
                grad[c] += jac[e, c] * resid[e]
            for c2 in range(d):
                total = damping if c == c2 else 0.0
                for e in range(3 * k):
                    total += jac[e, c] * jac[e, c2]
                normal[c, c2] = total
        _solve_spd(normal, grad)  # grad becomes the step
        for c in range(d):
            row[0, dofs[c]] += grad[c] / to_rad
        _fk_frame(row, 0, chain, parents, link, vct, axis0, col_start, nchan, chan_kind, chan_axis, to_rad,
                  cm_per_unit, W, pos)


@njit(cache=True, nogil=True, error_model="numpy")
def _solve_spd(a, b):
    """b := a^-1 b for a symmetric positive definite `a` (Cholesky, in place; `a` is overwritten).
    A matrix that is not (numerically), from a hostile skeleton, gives NaN, never an exception:
    the reader refuses values that are not finite."""
    n = a.shape[0]
    for i in range(n):
        for k in range(i + 1):
            total = a[i, k]
            for p in range(k):
                total -= a[i, p] * a[k, p]
            a[i, k] = math.sqrt(total) if i == k else total / a[k, k]
    for i in range(n):
        total = b[i]
        for p in range(i):
            total -= a[i, p] * b[p]
        b[i] = total / a[i, i]
    for i in range(n - 1, -1, -1):
        total = b[i]
        for p in range(i + 1, n):
            total -= a[p, i] * b[p]
        b[i] = total / a[i, i]


@njit(cache=True, nogil=True)
def fk_positions(values, parents, link, vct, axis0, col_start, nchan, chan_kind, chan_axis, to_rad, cm_per_unit):
    """kinematics.forward(...).positions: (F, J, 3) cm."""
    F = values.shape[0]
    J = parents.shape[0]
    out = np.empty((F, J, 3))
    every = np.arange(J)
    W = np.empty((J, 3, 3))
    for f in range(F):
        _fk_frame(values, f, every, parents, link, vct, axis0, col_start, nchan, chan_kind, chan_axis,
                  to_rad, cm_per_unit, W, out[f])
    return out


@njit(cache=True, nogil=True)
def fk_probed(values, cols, shifts, parents, link, vct, axis0, col_start, nchan, chan_kind, chan_axis, to_rad,
              cm_per_unit):
    """fk_positions of each frame of `values` (F, C) with column cols[k] moved by shifts[k]: (F, K, J, 3),
    bit for bit. Only the column's joint and its descendants are made again: no other joint reads it."""
    F = values.shape[0]
    J = parents.shape[0]
    K = cols.shape[0]
    out = np.empty((F, K, J, 3))
    every = np.arange(J)
    W = np.empty((J, 3, 3))
    pos = np.empty((J, 3))
    Wk = np.empty((J, 3, 3))
    row = np.empty((1, values.shape[1]))
    below = np.empty(J, dtype=np.bool_)
    owner = np.full(values.shape[1], -1)  # the joint that reads each column
    for j in range(J):
        if col_start[j] >= 0:
            for k in range(nchan[j]):
                owner[col_start[j] + k] = j
    subtrees = []
    for k in range(K):  # parents come before children
        top = owner[cols[k]]
        for j in range(J):
            below[j] = j == top or (j > top and parents[j] >= 0 and below[parents[j]])
        subtrees.append(np.flatnonzero(below))
    for f in range(F):
        _fk_frame(values, f, every, parents, link, vct, axis0, col_start, nchan, chan_kind, chan_axis,
                  to_rad, cm_per_unit, W, pos)
        for k in range(K):
            row[0, :] = values[f, :]
            row[0, cols[k]] = values[f, cols[k]] + shifts[k]
            Wk[:, :, :] = W
            out[f, k] = pos
            _fk_frame(row, 0, subtrees[k], parents, link, vct, axis0, col_start, nchan, chan_kind, chan_axis,
                      to_rad, cm_per_unit, Wk, out[f, k])
    return out


@njit(cache=True, nogil=True)
def fk_joint_distances(values, original, parents, link, vct, axis0, col_start, nchan, chan_kind, chan_axis,
                       to_rad, cm_per_unit):
    """metrics.joint_distances of fk_positions(values) and `original`: (F, J) cm."""
    F = values.shape[0]
    J = parents.shape[0]
    every = np.arange(J)
    W = np.empty((J, 3, 3))
    pos = np.empty((J, 3))
    d = np.empty((F, J))
    for f in range(F):
        _fk_frame(values, f, every, parents, link, vct, axis0, col_start, nchan, chan_kind, chan_axis,
                  to_rad, cm_per_unit, W, pos)
        for j in range(J):
            x = pos[j, 0] - original[f, j, 0]
            y = pos[j, 1] - original[f, j, 1]
            z = pos[j, 2] - original[f, j, 2]
            d[f, j] = math.sqrt(x * x + y * y + z * z)
    return d


@njit(cache=True, nogil=True)
def fk_shell_distances(values, original, shell_cm, origin_at, rotation_of, axes, parents, link, vct, axis0, col_start,
                       nchan, chan_kind, chan_axis, to_rad, cm_per_unit):
    """metrics.shell_errors of channel `values` against channel `original` (both (F, C)): (F, B) cm,
    per frame and shell frame (`metrics.shell_bones`: `origin_at`, `rotation_of`) the worst of its
    three vertices `shell_cm` along the axes of the world rotation R_j = C_j^T W_j (`axes`: C)."""
    F = values.shape[0]
    J = parents.shape[0]
    B = origin_at.shape[0]
    every = np.arange(J)
    W = np.empty((J, 3, 3))
    Wo = np.empty((J, 3, 3))
    pos = np.empty((J, 3))
    poso = np.empty((J, 3))
    d = np.empty((F, B))
    for f in range(F):
        _fk_frame(values, f, every, parents, link, vct, axis0, col_start, nchan, chan_kind, chan_axis,
                  to_rad, cm_per_unit, W, pos)
        _fk_frame(original, f, every, parents, link, vct, axis0, col_start, nchan, chan_kind, chan_axis,
                  to_rad, cm_per_unit, Wo, poso)
        for b in range(B):
            o = origin_at[b]
            j = rotation_of[b]
            worst = 0.0
            for k in range(3):  # vertex k: the origin's move plus shell_cm x (row k of R' - R)
                sq = 0.0
                for col in range(3):
                    turn = 0.0
                    for i in range(3):
                        turn += axes[j, i, k] * (W[j, i, col] - Wo[j, i, col])
                    x = pos[o, col] - poso[o, col] + shell_cm * turn
                    sq += x * x
                if sq > worst:
                    worst = sq
            d[f, b] = math.sqrt(worst)
    return d


@njit(cache=True, nogil=True)
def fk_distances(values, original, parents, link, vct, axis0, col_start, nchan, chan_kind, chan_axis,
                 to_rad, cm_per_unit):
    """(mean, max) of fk_joint_distances (mean as np.mean: pairwise sum)."""
    flat = fk_joint_distances(values, original, parents, link, vct, axis0, col_start, nchan, chan_kind, chan_axis,
                              to_rad, cm_per_unit).ravel()
    mx = -math.inf
    for v in flat:
        if v > mx or v != v:
            mx = v
    return np_sum(flat) / flat.size, mx


@njit(cache=True, nogil=True)
def twist_reference(values, ref_joints, ref_cols, ref_a0, ref_a1, to_rad):
    """positions.true_twists: (F, NR, 3, 3) euler_matrix of the 2-dof solved bones' original angles."""
    F = values.shape[0]
    NR = ref_joints.shape[0]
    out = np.empty((F, NR, 3, 3))
    ra = np.empty((3, 3))
    rb = np.empty((3, 3))
    for f in range(F):
        for r in range(NR):
            if ref_cols[r, 0] < 0:
                for i in range(3):
                    for k in range(3):
                        out[f, r, i, k] = 1.0 if i == k else 0.0
                continue
            _axis_rot(ref_a0[r], values[f, ref_cols[r, 0]] * to_rad, ra)
            _axis_rot(ref_a1[r], values[f, ref_cols[r, 1]] * to_rad, rb)
            _mm(ra, rb, out[f, r])
    return out
