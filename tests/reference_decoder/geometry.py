"""Lossy clips: from dequantised coefficients to AMC channel values.

Implements docs/format.md §10, "Decoding a lossy clip: from coefficients to AMC values" (its
sections cited as §10.N below): inverse temporal transforms (§10.2), root track scaling and PCA
reconstruction (§10.3), tensor classes (§10.4), segmented takes (§10.5), pose weights (§10.6), the
ASF skeleton (§10.7), marker decoding (§10.8), the five representations' inverses (§10.9),
inverse kinematics (§10.10), the foot lock (§10.11), frame patches (§10.12) and the output checks
(§10.13, §10.14).

Everything is float64. Per-frame quantities are numpy arrays with frames on axis 0; a rotation
per frame is an (F, 3, 3) array. Row vectors throughout: a point p is rotated as p @ R.
"""
import math
import re

import numpy as np

# §10.7, `:units length` given as a unit's name: cm per file unit
NAMED_LENGTHS = {**dict.fromkeys(("m", "meter", "meters", "metre", "metres"), 100.0),
                 **dict.fromkeys(("cm", "centimeter", "centimeters", "centimetre", "centimetres"), 1.0),
                 **dict.fromkeys(("mm", "millimeter", "millimeters", "millimetre", "millimetres"), 0.1),
                 **dict.fromkeys(("in", "inch", "inches"), 2.54)}
import pywt
import scipy.fft

PI = math.pi
DEG = PI / 180.0
YAW_RADIUS_CM = 50.0
UNIVERSAL_HEIGHT_CM = 158.9588
HEIGHT_BONES = ("lhipjoint", "lfemur", "ltibia", "lowerback", "upperback", "thorax",
                "lowerneck", "upperneck", "head")
UNIVERSAL_LENGTH_CM = {  # §10.9, CMU subject 07
    "lhipjoint": 15.1375, "rhipjoint": 14.4792, "lowerback": 12.6439,
    "lfemur": 39.0856, "rfemur": 40.3851, "upperback": 12.4247,
    "ltibia": 41.7975, "rtibia": 40.2420, "thorax": 12.4919,
    "lfoot": 11.2893, "rfoot": 11.9191, "lowerneck": 8.2594,
    "ltoes": 5.6818, "rtoes": 5.9602, "upperneck": 8.5130,
    "head": 8.6053, "lclavicle": 19.1177, "rclavicle": 19.2964,
    "lhumerus": 28.0391, "lradius": 18.9513, "lwrist": 9.4757,
    "lhand": 4.4984, "lfingers": 3.6268, "lthumb": 5.2073,
    "rhumerus": 29.4560, "rradius": 18.9938, "rwrist": 9.4969,
    "rhand": 3.5021, "rfingers": 2.8235, "rthumb": 4.0539,
}
MARKER_REPRESENTATIONS = ("positions", "aligned", "scaled", "normalised")
ROOT_TRACK_REPRESENTATIONS = ("aligned", "scaled", "normalised")
AXIS = {"x": 0, "y": 1, "z": 2}


# --------------------------------------------------------------------------- conventions

def after(k):
    """The two axes after axis k: x -> (y, z), y -> (z, x), z -> (x, y)."""
    return (k + 1) % 3, (k + 2) % 3


def rot(k, theta):
    """Rot(a, θ) (Conventions): one 3x3 matrix per angle, shape theta.shape + (3, 3)."""
    theta = np.asarray(theta, dtype=np.float64)
    b, c = after(k)
    m = np.zeros(theta.shape + (3, 3))
    cos, sin = np.cos(theta), np.sin(theta)
    m[..., k, k] = 1.0
    m[..., b, b] = cos
    m[..., c, c] = cos
    m[..., b, c] = sin
    m[..., c, b] = -sin
    return m


def euler(angles, axes):
    """Euler(θ, "a1a2a3") = Rot(a1, θ1) @ Rot(a2, θ2) @ ... (Conventions); angle i is about axes[i]."""
    angles = np.asarray(angles, dtype=np.float64)
    m = np.broadcast_to(np.eye(3), angles.shape[:-1] + (3, 3)).copy()
    for i, letter in enumerate(axes):
        m = m @ rot(AXIS[letter], angles[..., i])
    return m


def wrap(theta):
    """wrap(θ) = ((θ + π) mod 2π) - π, floored modulo (Conventions)."""
    return np.mod(theta + PI, 2.0 * PI) - PI


def angle_about(k, m):
    """angle_about(a, M) = atan2(M[b][c] - M[c][b], M[b][b] + M[c][c]) (Conventions)."""
    b, c = after(k)
    return np.arctan2(m[..., b, c] - m[..., c, b], m[..., b, b] + m[..., c, c])


def unwrap(theta):
    """unwrap along frames (axis 0), as the Conventions define it (numpy.unwrap with defaults)."""
    theta = np.asarray(theta, dtype=np.float64)
    if theta.shape[0] < 2:
        return theta.copy()
    d = np.diff(theta, axis=0)
    m = np.mod(d + PI, 2.0 * PI) - PI
    m[(m == -PI) & (d > 0)] = PI
    corr = m - d
    corr[np.abs(d) < PI] = 0.0
    out = theta.copy()
    out[1:] += np.cumsum(corr, axis=0)
    return out


def norm(v):
    """Euclidean length along the last axis."""
    return np.sqrt(np.sum(v * v, axis=-1))


def frame(x, y):
    """frame(x, y) (Conventions): rows x̂, ŷ, x̂ × ŷ, per frame; x, y of shape (F, 3)."""
    xh = x / np.maximum(norm(x), 1e-300)[:, None]
    yp = y - np.sum(y * xh, axis=-1)[:, None] * xh
    yh = yp / np.maximum(norm(yp), 1e-300)[:, None]
    return np.stack([xh, yh, np.cross(xh, yh)], axis=1)


def transpose(m):
    return np.swapaxes(m, -1, -2)


# --------------------------------------------------------------------------- §10.2 transforms

def inverse_transform(coef, transform):
    """§10.2: the inverse temporal transform of every column of an n x K matrix."""
    kind = transform["id"]
    if kind == "identity":
        return coef.copy()
    if kind == "dct":
        # orthonormal DCT-III, the inverse of the orthonormal DCT-II
        return scipy.fft.idct(coef, type=2, norm="ortho", axis=0)
    if kind == "dct-edges":
        out = scipy.fft.idct(coef, type=2, norm="ortho", axis=0)
        n, width = coef.shape
        edges = min(int(transform["edge_columns"]), width) if n >= 3 else 0
        c = np.sqrt(n * (n * n - 1) / 12.0)
        for j in range(edges):  # the line through the ends, plus sines that vanish there
            column = coef[:, j].astype(np.float64)
            t = np.arange(n, dtype=np.float64)
            x = column[0] / np.sqrt(n) + column[1] * (t - (n - 1) / 2) / c
            x[1:-1] += scipy.fft.idst(column[2:], type=1, norm="ortho")
            out[:, j] = x
        return out
    if kind == "dwt":
        wavelet = pywt.Wavelet(transform["wavelet"])
        lo = np.asarray(wavelet.rec_lo, dtype=np.float64)
        hi = np.asarray(wavelet.rec_hi, dtype=np.float64)
        taps = len(lo)
        level = transform["level"]
        if level is None:
            level = max_level(coef.shape[0], taps)
        return inverse_dwt(coef, int(level), lo, hi)
    if kind == "poly":
        return inverse_poly(coef, int(transform["knot_spacing"]))
    raise ValueError(f"unknown transform {kind!r}")


def inverse_poly(c, spacing):
    """§10.2 poly: per segment, its Gram polynomials times its coefficients (listed by degree, then segment)."""
    n = c.shape[0]
    g = max(1, (n + spacing // 2) // spacing)
    bounds = [s * n // g for s in range(g + 1)]
    lengths = [bounds[s + 1] - bounds[s] for s in range(g)]
    per_segment = [[] for _ in range(g)]
    row = 0
    for d in range(max(lengths)):
        for s in range(g):
            if d < lengths[s]:
                per_segment[s].append(c[row])
                row += 1
    out = np.empty_like(c, dtype=np.float64)
    for s in range(g):
        out[bounds[s]:bounds[s + 1]] = gram(lengths[s]) @ np.array(per_segment[s])
    return out


def gram(size):
    """§10.2 poly: column k, the degree-k polynomial orthonormal over t_i = (2i - (L-1)) / (L-1)."""
    t = np.array([(2 * i - (size - 1)) / (size - 1) for i in range(size)]) if size > 1 else np.zeros(1)
    columns = [np.full(size, 1.0 / np.sqrt(size))]
    for _ in range(1, size):
        v = t * columns[-1]
        for _ in range(2):
            done = np.array(columns).T
            v = v - done @ (done.T @ v)
        columns.append(v / np.sqrt(np.sum(v * v)))
    return np.array(columns).T


def max_level(n, taps):
    """§10.2: 0 if n < F - 1, else floor(log2(n // (F - 1))) (pywt.dwt_max_level)."""
    if n < taps - 1:
        return 0
    return (n // (taps - 1)).bit_length() - 1


def inverse_dwt(c, level, lo, hi):
    """§10.2: [approximation (m//2, level-1) | odd sample (m%2) | details (m//2)], recursively."""
    m = c.shape[0]
    if level == 0 or m < 2:
        return c.copy()
    h = m // 2
    a = inverse_dwt(c[0:h], level - 1, lo, hi)
    d = c[m - h:m]
    return np.concatenate([idwt_per(a, d, lo, hi), c[h:m - h]], axis=0)


def idwt_per(a, d, lo, hi):
    """§10.2: periodized one-level synthesis of two length-h inputs into N = 2h samples."""
    h = a.shape[0]
    n = 2 * h
    taps = len(lo)
    x = np.zeros((n,) + a.shape[1:])
    i = np.arange(h)
    for k in range(taps):
        # for a fixed k the targets 2i + k - (F/2 - 1) are distinct modulo N
        x[(2 * i + k - (taps // 2 - 1)) % n] += a * lo[k] + d * hi[k]
    return x


# --------------------------------------------------------------------------- §10.3, §10.5

def reconstruct(coefficients, transform, stream, class_index, rows, has_root):
    """§10.3: one coded stream -> (weighted poses n x M, root track n x 4 or None)."""
    mean, basis, pose, root = coefficients(stream, class_index, rows)
    wposes = mean + inverse_transform(pose, transform) @ basis.T  # with Q = 0 the product is zero
    track = None
    if has_root:
        if root is None:
            raise ValueError(f"{stream}: the representation needs a root track")
        track = inverse_transform(root, transform) / np.array([1.0, 1.0, 1.0, YAW_RADIUS_CM])
    return wposes, track


def crossfade_weight(f, s, count, first, frames, h):
    """§10.5: segment s's weight at take frame f (1 inside its own frames, linear over each cut)."""
    if h == 0:  # hard cut
        return 1.0 if first <= f < first + frames else 0.0
    g = 1.0
    if s > 0:
        g = min(g, min(max((f + 0.5 - first + h) / (2 * h), 0.0), 1.0))
    if s < count - 1:
        g = min(g, min(max((first + frames + h - (f + 0.5)) / (2 * h), 0.0), 1.0))
    return g


def weighted_take(settings, row, coefficients, has_root, prediction=None):
    """§10.3-§10.5: the take's weighted poses (frames x M) and root track (frames x 4 or None).

    The unsegmented clip's own stream is requested as stream name None (the row does not know
    its index NNNNN; the orchestration's callback does); segments by their `stream` names.
    """
    transform = settings["transform"]
    n = row["frames"]
    if "segments" not in row:
        wposes, track = reconstruct(coefficients, transform, None, row["class"], n, has_root)
        if "tensor_at" in row:  # §10.4 (format 11 on): plus the class's tensor model's prediction
            wposes = wposes + prediction(row)
        return wposes, track
    if not settings.get("segment", False):
        raise ValueError("row has segments but settings.segment is not true")
    v = row["segment_overlap"]
    h = v // 2
    parts = row["segments"]
    wposes, track = None, None
    for s, part in enumerate(parts):
        first, frames = part["first"], part["frames"]
        lo, hi = max(first - v, 0), min(first + frames + v, n)
        piece, piece_root = reconstruct(coefficients, transform, part["stream"], part["class"], hi - lo,
                                        has_root)
        if wposes is None:
            wposes = np.zeros((n, piece.shape[1]))
            track = np.zeros((n, 4)) if has_root else None
        elif piece.shape[1] != wposes.shape[1]:
            raise ValueError(f"{part['stream']}: pose width {piece.shape[1]} differs from {wposes.shape[1]}")
        g = np.array([crossfade_weight(f, s, len(parts), first, frames, h) for f in range(lo, hi)])
        wposes[lo:hi] += g[:, None] * piece
        if has_root:
            track[lo:hi] += g[:, None] * piece_root
    return wposes, track


# --------------------------------------------------------------------------- §10.7 skeleton

NUMBER = re.compile(r"[+-]?(\d+(\.\d*)?|\.\d+)([eE][+-]?\d+)?\Z")


def number(word):
    if not NUMBER.match(word):
        raise ValueError(f"ASF: not a number: {word!r}")
    return float(word)


def asf_lines(skeleton_text):
    """§10.7: bytes (Latin-1 codes), BOM dropped, UTF-8 if valid else Latin-1; stripped, no blanks/comments."""
    raw = skeleton_text.encode("latin-1")
    if raw.startswith(b"\xef\xbb\xbf"):
        raw = raw[3:]
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError:
        text = raw.decode("latin-1")
    for line in re.split(r"\r\n|\n|\r", text):
        line = line.strip()
        if line and not line.startswith("#"):
            yield line


class Skeleton:
    """§10.7: the skeleton model (joints in pre-order from the root, axis matrices, bone vectors, ...)."""

    def __init__(self, skeleton_text, axes_from_positions):
        units, root, bones, hierarchy = self.parse(skeleton_text)
        self.radians = units.get("angle", "deg").lower().startswith("rad")
        length = units.get("length", "1").lower()  # §10.7: a factor, or a unit's name
        self.cm_per_unit = NAMED_LENGTHS[length] if length in NAMED_LENGTHS else 2.54 / number(length)
        u = 1.0 if self.radians else DEG

        # joints: root, then a pre-order walk through the hierarchy
        self.names, self.parent = ["root"], [-1]
        stack = [(child, 0) for child in reversed(hierarchy.get("root", []))]
        while stack:
            name, parent = stack.pop()
            if name in self.names:
                raise ValueError(f"ASF: bone {name!r} appears twice in the hierarchy")
            if name not in bones:
                raise ValueError(f"ASF: hierarchy names an unknown bone {name!r}")
            self.names.append(name)
            self.parent.append(parent)
            stack.extend((child, len(self.names) - 1) for child in reversed(hierarchy.get(name, [])))
        count = len(self.names)

        # per joint: axis matrix C, bone vector V (cm), channels
        self.C = np.zeros((count, 3, 3))
        self.V = np.zeros((count, 3))
        self.channels = []
        for j, name in enumerate(self.names):
            if j == 0:
                self.C[j] = euler(np.array(root["orientation"]) * u, root["axis"])
                channels = root["order"]
            else:
                bone = bones[name]
                self.C[j] = euler(np.array(bone["axis"]) * u, bone["axis_order"])
                self.V[j] = np.array(bone["direction"]) * bone["length"] * self.cm_per_unit
                channels = bone["dof"]
            self.channels.append(channels)
        self.derive(axes_from_positions)

    @classmethod
    def from_model(cls, names, parent, V, channels, cm_per_unit, axes_from_positions):
        """A model given joint by joint rather than by an ASF (a BVH hierarchy's, "Decoding a BVH
        clip"): every axis matrix the identity, angles in degrees, V in cm, parents first."""
        sk = cls.__new__(cls)
        sk.names, sk.parent, sk.channels = list(names), list(parent), [list(c) for c in channels]
        sk.radians, sk.cm_per_unit = False, float(cm_per_unit)
        sk.V = np.array(V, dtype=np.float64).reshape(len(sk.names), 3)
        sk.C = np.broadcast_to(np.eye(3), (len(sk.names), 3, 3)).copy()
        if len(set(sk.names)) != len(sk.names):
            raise ValueError("model: two joints of one name")
        if any(not 0 <= p < j for j, p in enumerate(sk.parent) if j) or sk.parent[:1] != [-1]:
            raise ValueError("model: a parent that does not precede its joint")
        sk.derive(axes_from_positions)
        return sk

    def derive(self, axes_from_positions):
        """§10.7, from the joints' names, parents, C, V and channels: rotation axes, lengths, short bones,
        root proxy, faux matrices, solved bones and height."""
        count = len(self.names)
        self.index = {name: j for j, name in enumerate(self.names)}
        for j in range(1, count):
            if any(ch[0] != "r" for ch in self.channels[j]):
                raise ValueError(f"bone {self.names[j]!r} has a dof other than rx ry rz: cannot decode")
        self.axes = ["".join(ch[1] for ch in channels if ch[0] == "r") for channels in self.channels]
        self.L = norm(self.V)

        # derived: short bones, root proxy, faux matrices, solved bones, height
        self.short = [j >= 1 and self.L[j] < 1.0 for j in range(count)]
        self.proxy = next((j for j in range(1, count) if self.parent[j] == 0 and not self.axes[j]), None)
        self.B = np.broadcast_to(np.eye(3), (count, 3, 3)).copy()
        for j in range(1, count):
            if not self.short[j]:
                x = self.V[j] / self.L[j]
                e = np.zeros(3)
                e[int(np.argmin(np.abs(x)))] = 1.0
                y = e - np.dot(e, x) * x
                y = y / norm(y)
                self.B[j] = np.stack([x, y, np.cross(x, y)])
        self.solved = [False] * count
        if axes_from_positions:
            for j in range(1, count):
                if self.short[j] or j == self.proxy or len(self.axes[j]) > 2:
                    continue
                x = self.V[j] / self.L[j]
                self.solved[j] = all(abs(np.dot(self.C[j][AXIS[a]], x)) < 0.5 for a in self.axes[j])
        if all(name in self.index for name in HEIGHT_BONES):
            height = 0.0
            for name in HEIGHT_BONES:
                height += float(self.L[self.index[name]])
        else:
            base = np.zeros((count, 3))
            for j in range(1, count):
                base[j] = base[self.parent[j]] + self.V[j]
            height = float(base[:, 1].max() - base[:, 1].min())
        self.height = height

    @staticmethod
    def parse(skeleton_text):
        """§10.7: the sections the decoder uses: :units, :root, :bonedata, :hierarchy."""
        units = {}
        root = {"order": ["tx", "ty", "tz", "rx", "ry", "rz"], "axis": "xyz", "orientation": [0.0, 0.0, 0.0]}
        bones, hierarchy = {}, {}
        section, bone, in_hierarchy = None, None, False
        for line in asf_lines(skeleton_text):
            words = line.split()
            if line.startswith(":"):
                section, bone, in_hierarchy = words[0].lower(), None, False
                continue
            key = words[0].lower()
            if section == ":units":
                if len(words) >= 2:
                    units[key] = words[1]
            elif section == ":root":
                if key == "order":
                    root["order"] = [w.lower() for w in words[1:]]
                elif key == "axis":
                    root["axis"] = words[1].lower()
                elif key == "orientation":
                    root["orientation"] = [number(w) for w in words[1:4]]
            elif section == ":bonedata":
                if key == "begin":
                    bone = {"name": None, "direction": [0.0, 0.0, 0.0], "length": 0.0,
                            "axis": [0.0, 0.0, 0.0], "axis_order": "xyz", "dof": []}
                elif key == "end" and bone is not None:
                    bones[bone["name"]] = bone
                    bone = None
                elif bone is None:
                    continue
                elif key == "name":
                    bone["name"] = words[1]
                elif key == "direction":
                    bone["direction"] = [number(w) for w in words[1:4]]
                elif key == "length":
                    bone["length"] = number(words[1])
                elif key == "axis":
                    bone["axis"] = [number(w) for w in words[1:4]]
                    if len(words) > 4:
                        bone["axis_order"] = words[4].lower()
                elif key == "dof":
                    bone["dof"] = [w.lower() for w in words[1:]]
            elif section == ":hierarchy":
                if key == "begin" and len(words) == 1:
                    in_hierarchy = True
                elif key == "end" and len(words) == 1:
                    in_hierarchy = False
                elif in_hierarchy:
                    hierarchy.setdefault(words[0], []).extend(words[1:])
        return units, root, bones, hierarchy


# --------------------------------------------------------------------------- §10.8 marker decoding

def marker_widths(sk, o):
    """§10.8: the pose columns' blocks: (positions, y axes of the stored bones, short x axes, root axes)."""
    count = len(sk.names)
    stored = [j for j in range(1, count) if not sk.solved[j]]
    shorts = [j for j in range(1, count) if sk.short[j]]
    return 3 * (count - o), stored, shorts, (6 if sk.proxy is None else 0)


def decode_markers(sk, poses, o, flips):
    """§10.8: unweighted marker pose P (F x M) -> world rotations R (J, F, 3, 3), positions p (J, F, 3)."""
    count, frames = len(sk.names), poses.shape[0]
    n_pos, stored, shorts, n_root = marker_widths(sk, o)
    width = n_pos + 3 * len(stored) + 3 * len(shorts) + n_root
    if poses.shape[1] != width:
        raise ValueError(f"pose width {poses.shape[1]}, the skeleton needs {width}")
    p = np.zeros((count, frames, 3))
    for j in range(o, count):
        p[j] = poses[:, 3 * (j - o):3 * (j - o) + 3]
    col = n_pos
    y_axis = {}
    for j in stored:
        y_axis[j] = poses[:, col:col + 3]
        col += 3
    x_axis = {}
    for j in shorts:
        x_axis[j] = poses[:, col:col + 3]
        col += 3

    root_axes = None if sk.proxy is not None else (poses[:, col:col + 3], poses[:, col + 3:col + 6])
    check_directions(sk, p, x_axis, y_axis, root_axes)
    R = np.zeros((count, frames, 3, 3))
    for j in stored:  # step 2
        x = x_axis[j] if sk.short[j] else p[j] - p[sk.parent[j]]
        R[j] = transpose(sk.B[j]) @ frame(x, y_axis[j])
    if sk.proxy is not None:  # step 3
        R[0] = R[sk.proxy]
    else:
        R[0] = frame(poses[:, col:col + 3], poses[:, col + 3:col + 6])
    for j in range(1, count):  # step 4, increasing joint order
        if sk.solved[j]:
            parent = sk.parent[j]
            m = solve(sk, j, p[j] - p[parent], R[parent], flips.get(sk.names[j]))
            R[j] = transpose(sk.C[j]) @ m @ sk.C[j] @ R[parent]
    return R, p


MIN_DIRECTION = 1e-6


def check_directions(sk, p, x_axis, y_axis, root_axes):
    """§10.8's rule before decoding: every x (a bone from its parent, or a short bone's x axis, or
    the root's), and every y less its part along x (as frame() makes it), at least MIN_DIRECTION long."""
    def across(x, y):
        xh = x / np.maximum(norm(x), 1e-300)[:, None]
        return y - np.sum(y * xh, axis=-1)[:, None] * xh

    vectors = []
    for j in range(1, len(sk.names)):
        x = x_axis[j] if sk.short[j] else p[j] - p[sk.parent[j]]
        vectors.append((sk.names[j], x))
        if j in y_axis:
            vectors.append((sk.names[j], across(x, y_axis[j])))
    if root_axes is not None:
        vectors += [(sk.names[0], root_axes[0]), (sk.names[0], across(*root_axes))]
    for name, v in vectors:
        if not np.all(norm(v) >= MIN_DIRECTION):
            raise ValueError(f"bone {name}: a direction shorter than {MIN_DIRECTION} (degenerate pose)")


def solve(sk, j, bone, r_parent, flip_ranges):
    """§10.8 solve(j): the rotation M (F, 3, 3) in j's axis frame that points bone j along `bone`."""
    frames = bone.shape[0]
    c = sk.C[j]
    u = sk.V[j] @ c.T
    u = u / norm(u)
    t = np.einsum("fi,fji->fj", bone, r_parent)  # bone @ R_p^T, per frame
    t = t @ c.T
    t = t / np.maximum(norm(t), 1e-300)[:, None]

    def about(k, uu, tt):
        b, cc = after(k)
        return np.arctan2(tt[..., cc], tt[..., b]) - np.arctan2(uu[..., cc], uu[..., b])

    axes = sk.axes[j]
    if len(axes) == 0:
        return np.broadcast_to(np.eye(3), (frames, 3, 3)).copy()
    if len(axes) == 1:
        k = AXIS[axes]
        return rot(k, about(k, u, t))
    a1, a2 = AXIS[axes[0]], AXIS[axes[1]]
    b, cc = after(a1)
    rho = math.hypot(u[b], u[cc])
    phi = math.atan2(u[cc], u[b])
    if a2 == b:
        tau = np.arccos(np.clip(t[:, b] / rho, -1.0, 1.0))
        taus = (tau, -tau)
    else:
        tau = np.arcsin(np.clip(t[:, cc] / rho, -1.0, 1.0))
        taus = (tau, PI - tau)
    s, r = [], []
    for tau_i in taus:
        s_i = wrap(tau_i - phi)
        u_i = np.einsum("i,fij->fj", u, rot(a1, s_i))  # u @ Rot(a1, s_i), per frame
        s.append(s_i)
        r.append(wrap(about(a2, u_i, t)))
    other = np.maximum(np.abs(s[1]), np.abs(r[1])) < np.maximum(np.abs(s[0]), np.abs(r[0]))
    if flip_ranges:
        for start, end in zip(flip_ranges[0::2], flip_ranges[1::2]):
            other[start:end] = ~other[start:end]
    s_pick = np.where(other, s[1], s[0])
    r_pick = np.where(other, r[1], r[0])
    return rot(a1, s_pick) @ rot(a2, r_pick)


# --------------------------------------------------------------------------- §10.9 representations

def rotations_and_root(sk, representation, poses, track, flips):
    """§10.9: unweighted poses (+ root track) -> world rotations R (J, F, 3, 3), root position T0 (F, 3) cm."""
    count = len(sk.names)
    if representation == "positions":
        R, p = decode_markers(sk, poses, 0, flips)
        return R, p[0]
    n_pos = 3 * (count - 1)
    poses = poses.copy()
    if representation == "scaled":
        scale = UNIVERSAL_HEIGHT_CM / sk.height
        poses[:, :n_pos] = poses[:, :n_pos] / scale
    elif representation == "normalised":
        poses[:, :n_pos] = normalised_positions(sk, poses[:, :n_pos])
    elif representation != "aligned":
        raise ValueError(f"unknown representation {representation!r}")
    R, _ = decode_markers(sk, poses, 1, flips)
    R = R @ rot(1, track[:, 3])  # R_j = R'_j @ Rot(y, ψ), every joint
    return R, track[:, 0:3]


def normalised_positions(sk, columns):
    """§10.9 normalised: rebuild p_1..p_{J-1} with the clip's own bone lengths."""
    count, frames = len(sk.names), columns.shape[0]
    p = np.zeros((count, frames, 3))
    for j in range(1, count):
        p[j] = columns[:, 3 * (j - 1):3 * j]
    rebuilt = np.zeros((count, frames, 3))
    for j in range(1, count):
        length = float(sk.L[j])
        name = sk.names[j]
        universal = UNIVERSAL_LENGTH_CM[name] if (not sk.short[j] and name in UNIVERSAL_LENGTH_CM) else length
        factor = universal / length if length > 0 else 1.0
        b = (p[j] - p[sk.parent[j]]) * (1.0 / factor)
        rebuilt[j] = rebuilt[sk.parent[j]] + b  # parents precede children
    return np.concatenate([rebuilt[j] for j in range(1, count)], axis=1) if count > 1 else columns


# --------------------------------------------------------------------------- §10.10 inverse kinematics

def three_axis_solution(m, axes):
    """§10.10, 3 axes: one exact (first, middle, last) per frame, before continuity."""
    a, b, c = (AXIS[letter] for letter in axes)
    sgn = 1.0 if (b - a) % 3 == 1 else -1.0
    cm = np.hypot(m[:, b, c], m[:, c, c])
    first = np.arctan2(sgn * m[:, b, c], m[:, c, c])
    middle = np.arctan2(-sgn * m[:, a, c], cm)
    locked = cm < 1e-9
    if locked.any():
        latest = 0.0
        for f in range(len(first)):
            if locked[f]:
                first[f] = latest
            else:
                latest = first[f]
    partial = rot(a, first) @ rot(b, middle)
    last = angle_about(c, transpose(partial) @ m)
    return first, middle, last


def euler_angles(m, axes):
    """§10.10 euler_angles(M, axes): (F, len(axes)) radians, unwrapped along frames."""
    frames = m.shape[0]
    if len(axes) == 0:
        return np.zeros((frames, 0))
    if len(axes) == 1:
        return unwrap(angle_about(AXIS[axes], m))[:, None]
    if len(axes) == 3:
        canon = np.stack(three_axis_solution(m, axes), axis=1)
        alt = np.stack([canon[:, 0] + PI, PI - canon[:, 1], canon[:, 2] + PI], axis=1)
        switch = np.zeros(frames, dtype=bool)
        if frames > 1:
            stay_cost = np.sum(wrap(canon[1:] - canon[:-1]) ** 2, axis=1)
            switch_cost = np.sum(wrap(alt[1:] - canon[:-1]) ** 2, axis=1)
            switch[1:] = switch_cost < stay_cost
        take_alt = np.cumsum(switch) % 2 == 1
        return unwrap(np.where(take_alt[:, None], alt, canon))
    if len(axes) == 2:
        third = next(letter for letter in "xyz" if letter not in axes)
        f1, f2, f3 = three_axis_solution(m, axes + third)
        flip = np.abs(wrap(f3 + PI)) < np.abs(wrap(f3))
        f1 = np.where(flip, f1 + PI, f1)
        f2 = np.where(flip, PI - f2, f2)
        a1, a2 = AXIS[axes[0]], AXIS[axes[1]]
        for _ in range(20):
            g1 = angle_about(a1, m @ transpose(rot(a2, f2)))
            g2 = angle_about(a2, transpose(rot(a1, g1)) @ m)
            change = max(np.max(np.abs(wrap(g1 - f1)), initial=0.0),
                         np.max(np.abs(wrap(g2 - f2)), initial=0.0))
            f1, f2 = g1, g2
            if change < 1e-13:
                break
        return unwrap(np.stack([f1, f2], axis=1))
    raise ValueError(f"{len(axes)} rotation axes")


def channels_from_rotations(sk, row, R, root_position):
    """§10.10: world rotations + root position -> the row's AMC columns."""
    frames = R.shape[1]
    to_unit = 1.0 / DEG if row["angle_unit"] == "deg" else 1.0
    out = np.zeros((frames, sum(row["counts"])))
    col = 0
    for name, count in zip(row["bones"], row["counts"]):
        j = sk.index.get(name)
        if j is None:
            raise ValueError(f"layout bone {name!r} is not a joint of the skeleton")
        if count != len(sk.channels[j]):
            raise ValueError(f"layout bone {name!r}: {count} values, "
                             f"the skeleton has {len(sk.channels[j])} channels")
        c = sk.C[j]
        if j == 0:
            m = c @ R[0] @ c.T
        else:
            m = c @ R[j] @ transpose(R[sk.parent[j]]) @ c.T
        angles = euler_angles(m, sk.axes[j])
        n_rot = 0
        for i, channel in enumerate(sk.channels[j]):
            if channel[0] == "r":
                out[:, col + i] = angles[:, n_rot] * to_unit
                n_rot += 1
            else:  # root translation
                out[:, col + i] = root_position[:, AXIS[channel[1]]] / sk.cm_per_unit
        col += count
    return out


# --------------------------------------------------------------------------- the whole clip

def pose_weights(sk, representation, width, axis_weight_cm):
    """§10.6: w, per pose column."""
    count = len(sk.names)
    w = np.ones(width)
    if representation == "positions":
        w[3 * count:] = axis_weight_cm
    elif representation in ROOT_TRACK_REPRESENTATIONS:
        w[3 * (count - 1):] = axis_weight_cm
    return w


def lossy_channels(settings, format_version, row, skeleton, coefficients, prediction=None):
    """The clip's decoded AMC values, frames x sum(counts) float64 (pipeline steps 1-6, §10.2-§10.14).

    skeleton(axes_from_positions) -> the clip's Skeleton (§10.7: an ASF's; or a BVH hierarchy's model).

    coefficients(stream_name, class_index, rows) -> (mean, basis, pose, root) gives a stream's
    dequantised class basis and coefficients; stream_name is None for an unsegmented clip's own
    stream (clip/NNNNN) and the segment's `stream` otherwise.
    """
    representation = settings["representation"]
    if format_version >= 4:
        if "axes_from_positions" not in settings:
            raise ValueError("settings.axes_from_positions missing (format 4 stores it)")
        axes_from_positions = bool(settings["axes_from_positions"])
    else:
        axes_from_positions = False  # §10.14
    has_root = representation in ROOT_TRACK_REPRESENTATIONS
    if "tensor_at" in row and (format_version < 11 or "segments" in row):
        raise ValueError("tensor_at: format 11 on, in a row without segments")
    wposes, track = weighted_take(settings, row, coefficients, has_root, prediction)

    frames, width = row["frames"], sum(row["counts"])
    if wposes.shape[0] != frames:
        raise ValueError(f"decoded {wposes.shape[0]} frames, the row has {frames}")
    if representation == "channels":
        if wposes.shape[1] != width:
            raise ValueError(f"pose width {wposes.shape[1]} != sum(counts) {width}")
        values = wposes.copy()  # w = 1: the weighted poses are the AMC values
    elif representation in MARKER_REPRESENTATIONS:
        sk = skeleton(axes_from_positions)
        poses = wposes / pose_weights(sk, representation, wposes.shape[1], settings["axis_weight_cm"])
        flips = row.get("twist_flips", {})  # only 2-axis solved bones use them (§10.8)
        for name in flips:
            if name not in sk.index:
                raise ValueError(f"twist_flips names {name!r}, not a joint of the skeleton")
        R, root_position = rotations_and_root(sk, representation, poses, track, flips)
        values = channels_from_rotations(sk, row, R, root_position)
    else:
        raise ValueError(f"unknown representation {representation!r}")

    if values.shape != (frames, width):  # §10.13
        raise ValueError(f"decoded shape {values.shape}, expected {(frames, width)}")
    if not np.all(np.isfinite(values)) or np.any(np.abs(values) > 1e9):
        raise ValueError("decoded values not finite or beyond 1e9")
    return values


def add_patches(values, patches, row, sk):
    """§10.12: the frame patches added to the decoded values, in place (sk: the clip's Skeleton)."""
    step_cm, frames = patches
    to_unit = 180.0 / PI if row["angle_unit"] == "deg" else 1.0
    base = []
    for name, count in zip(row["bones"], row["counts"]):
        for channel in sk.channels[sk.index[name]][:count]:
            base.append(to_unit / 100.0 if channel[0] == "r" else 1.0 / sk.cm_per_unit)
    base = np.array(base)
    for frame, level, ints in frames:
        values[frame] = values[frame] + ints.astype(np.float64) * (base * (step_cm * 2.0 ** -level))


# --------------------------------------------------------------------------- §10.11 foot lock (format 9)

FOOT = re.compile(r"toe|foot", re.IGNORECASE)
LOCK_RAMP, LOCK_ROUNDS, LOCK_DAMPING = 8, 3, 4.0


def foot_joints(sk):
    """§10.11: the joints named like a toe or a foot, in joint order."""
    return [j for j, name in enumerate(sk.names) if FOOT.search(name)]


def forward(sk, row, values):
    """Joint positions (F, J, 3) cm of AMC values laid out as the row says (§10.11)."""
    return forward_with_rotations(sk, row, values)[0]


def forward_with_rotations(sk, row, values):
    """(positions (F, J, 3) cm, world rotations (J, F, 3, 3)): R_j = C_j^T M_j C_j R_p, T_j = T_p + V_j R_j."""
    frames, to_rad = values.shape[0], (1.0 if row["angle_unit"] == "rad" else DEG)
    column = {}
    col = 0
    for name, count in zip(row["bones"], row["counts"]):
        column[sk.index[name]] = col
        col += count
    R = np.zeros((len(sk.names), frames, 3, 3))
    T = np.zeros((len(sk.names), frames, 3))
    for j in range(len(sk.names)):
        m = np.broadcast_to(np.eye(3), (frames, 3, 3)).copy()
        if j in column:
            for i, channel in enumerate(sk.channels[j]):
                v = values[:, column[j] + i]
                if channel[0] == "r":
                    m = m @ rot(AXIS[channel[1]], v * to_rad)
                else:
                    T[j][:, AXIS[channel[1]]] = v * sk.cm_per_unit
        base = np.eye(3) if j == 0 else R[sk.parent[j]]
        R[j] = sk.C[j].T @ m @ sk.C[j] @ base
        if j:
            T[j] = T[sk.parent[j]] + np.einsum("k,fkl->fl", sk.V[j], R[j])
    return np.transpose(T, (1, 0, 2)), R


def hold_planted_feet(values, stances, row, sk):
    """§10.11: each stance's foot joint held at its mean decoded position, in place."""
    feet, count = foot_joints(sk), values.shape[0]
    to_rad = 1.0 if row["angle_unit"] == "rad" else DEG
    column, col = {}, 0
    for name, n in zip(row["bones"], row["counts"]):
        column[sk.index[name]] = col
        col += n
    start = forward(sk, row, values)
    weight = np.zeros((len(feet), count))
    anchor = np.zeros((len(feet), count, 3))
    for n, (foot, first, frames) in enumerate(stances):
        end = first + frames
        before = stances[n - 1] if n and stances[n - 1][0] == foot else None
        after = stances[n + 1] if n + 1 < len(stances) and stances[n + 1][0] == foot else None
        ease_in = LOCK_RAMP if before is None else min(LOCK_RAMP, (first - before[1] - before[2]) // 2)
        ease_out = LOCK_RAMP if after is None else min(LOCK_RAMP, (after[1] - end) // 2)
        mean = start[first:end, feet[foot]].mean(axis=0)
        for t in range(first, end):
            weight[foot, t], anchor[foot, t] = 1.0, mean
        for length, frame_of in ((ease_in, lambda i, L: first - L - 1 + i), (ease_out, lambda i, L: end + L - i)):
            for i in range(1, length + 1):
                t = frame_of(i, length)
                if 0 <= t < count:
                    weight[foot, t] = 0.5 - 0.5 * math.cos(PI * i / (length + 1))
                    anchor[foot, t] = mean
    rotates = [j in column and any(c[0] == "r" for c in sk.channels[j]) for j in range(len(sk.names))]
    legs = {}
    for f, joint in enumerate(feet):
        path, above, j = [], 0, joint
        while j > 0 and above < 2:
            path.append(j)
            above += rotates[j] and not FOOT.search(sk.names[j])
            j = sk.parent[j]
        if path:
            legs.setdefault(path[-1], []).append((f, path))
    for top in sorted(legs):
        members = legs[top]
        chain = sorted({j for _, path in members for j in path})
        dof_channels = [(j, i) for j in chain if j in column for i, c in enumerate(sk.channels[j]) if c[0] == "r"]
        dofs = [column[j] + i for j, i in dof_channels]
        leg_feet = [f for f, _ in members]
        if not dofs:
            continue
        joints = [feet[f] for f in leg_feet]

        def jacobian(v, p, rotations, active):
            """§10.11: d position of foot / d angle (rad) = w x (position - parent's position)."""
            jac = np.zeros((len(joints), 3, len(dofs)))
            for c, (j, i) in enumerate(dof_channels):
                turn = np.eye(3)  # the rotations after channel i, then C_j R_p
                for later, channel in enumerate(sk.channels[j]):
                    if later > i and channel[0] == "r":
                        turn = turn @ rot(AXIS[channel[1]], v[0, column[j] + later] * to_rad)
                w = (turn @ sk.C[j] @ rotations[sk.parent[j]][0])[AXIS[sk.channels[j][i][1]]]
                for a, foot in enumerate(joints):
                    below = foot
                    while below > 0 and below != j:
                        below = sk.parent[below]
                    if active[a] and below == j:
                        jac[a, :, c] = np.cross(w, p[foot] - p[sk.parent[j]])
            return jac.reshape(3 * len(joints), len(dofs))

        def solve(frame_values, target, active, first_angles):
            """§10.11: ROUNDS rounds of damped Gauss-Newton, in place."""
            for _ in range(LOCK_ROUNDS):
                reached, rotations = forward_with_rotations(sk, row, frame_values)
                residual = np.where(active[:, None], target - reached[0, joints], 0.0).ravel()
                jac = jacobian(frame_values, reached[0], rotations, active)
                gradient = jac.T @ residual - LOCK_DAMPING * (frame_values[0, dofs] - first_angles) * to_rad
                try:
                    step = np.linalg.solve(jac.T @ jac + LOCK_DAMPING * np.eye(len(dofs)), gradient)
                except np.linalg.LinAlgError:  # §10.11: no solution; the clip has no finite values
                    step = np.full(len(dofs), np.nan)
                frame_values[0, dofs] = frame_values[0, dofs] + step / to_rad

        for t in range(count):
            w = np.array([weight[f, t] for f in leg_feet])
            if not np.any(w > 0):
                continue
            anchors = np.array([anchor[f, t] for f in leg_feet])
            frame_values = values[t:t + 1].copy()
            first_angles = frame_values[0, dofs].copy()
            if np.any(w == 1.0):  # pass 1: the held joints alone
                solve(frame_values, anchors, w == 1.0, first_angles)
            easing = (w > 0) & (w < 1)
            if np.any(easing):  # pass 2: all, the easing ones from where pass 1 left them
                now = forward(sk, row, frame_values)[0, joints]
                target = np.where(easing[:, None], now + w[:, None] * (anchors - now), anchors)
                solve(frame_values, target, w > 0, first_angles)
            values[t, dofs] = frame_values[0, dofs]
