"""The `skeletons` stream of format 10 on: docs/format.md, "`skeletons` (format 10 on)"."""

import math
import re
from fractions import Fraction

from .container import Reader, dictionary, zstd_stream
from .streams import RangeDecoder

NUMBER = re.compile(rb"(?<![A-Za-z0-9_.])(-?)(0|[1-9][0-9]*)(?:\.([0-9]+))?(?:([eE])([-+])([0-9]{1,3}))?(?![A-Za-z0-9_.])")
DIRECTION = re.compile(rb"(?m)^[ \t]*direction[ \t]+\0[ \t]+\0[ \t]+\0[ \t\r]*$")
SECTION = re.compile(rb"(?m)^# AST/ASF file generated")
UNKNOWN = 137


def number(groups) -> dict | None:
    """A regex match's groups as the spec's fields; None beyond the digit limits (left as text)."""
    minus, whole, fraction, letter, sign, power = groups
    fraction = fraction or b""
    if len(whole) + len(fraction) > 40 or len(fraction) > 30:
        return None
    m = int(whole + fraction)
    return {"m": -m if minus else m, "d": len(fraction), "negative": minus == b"-",
            "letter": letter.decode() if letter else "", "x": int(sign + power) if letter else 0,
            "plus": sign == b"+", "w": len(power) if letter else 0}


def templated(text: bytes) -> tuple[bytes, list]:
    out, numbers, at = bytearray(), [], 0
    for match in NUMBER.finditer(text):
        fields = number(match.groups())
        if fields is None:
            continue
        out += text[at:match.start()] + b"\0"
        numbers.append(fields)
        at = match.end()
    return bytes(out + text[at:]), numbers


def printed(n: dict) -> bytes:
    digits = str(abs(n["m"])).rjust(n["d"] + 1, "0")
    text = ("-" if n["negative"] else "") + (digits if n["d"] == 0 else digits[:-n["d"]] + "." + digits[-n["d"]:])
    if n["letter"]:
        text += n["letter"] + ("+" if n["plus"] else "-") + str(abs(n["x"])).rjust(n["w"], "0")
    return text.encode()


def sections(name: str) -> list:
    text = dictionary(name)
    cuts = [m.start() for m in SECTION.finditer(text)] + [len(text)]
    return [templated(text[a:b]) for a, b in zip(cuts, cuts[1:])]


def families() -> list:
    out = []
    for (template, shared), (_, means) in zip(sections("asf.txt"), sections("asf_means.txt")):
        hints = [0 if printed(a) == printed(b) else UNKNOWN for a, b in zip(shared, means)]
        out.append({"template": template, "numbers": means, "hints": hints})
    return out


def read_int(rc: RangeDecoder, P: list) -> int:
    if rc.bit(P, 0) == 0:
        return 0
    negative = rc.bit(P, 1)
    L = 1
    while L < 136 and rc.bit(P, 1 + L) == 1:
        L += 1
    v = 2 ** (L - 1) + rc.direct(L - 1)
    return -v if negative else v


def scale(n: dict) -> int:
    return n["x"] - n["d"]


def prediction(i, n, numbers, R, companions) -> int:
    if R is None:
        return 0
    if i in companions:
        a, b = (numbers[j] for j in companions[i])
        F = min(scale(n), scale(a), scale(b))
        if F > 0 or max(scale(n) - F, scale(a) - F, scale(b) - F) > 30:
            return 0
        Q = 10 ** (-2 * F) - (a["m"] * 10 ** (scale(a) - F)) ** 2 - (b["m"] * 10 ** (scale(b) - F)) ** 2
        r = math.isqrt(Q) if Q > 0 else 0
        u = 10 ** (scale(n) - F)
        p = (2 * r + u) // (2 * u)
        if p >= 10**40:
            return 0
        return -p if R["numbers"][i]["m"] < 0 or R["numbers"][i]["negative"] else p
    mR, g = R["numbers"][i]["m"], scale(R["numbers"][i]) - scale(n)
    if abs(g) > 30:
        return 0
    if g >= 0:
        p = mR * 10**g
    else:
        u = 10 ** (-g)
        p = (1 if mR >= 0 else -1) * ((2 * abs(mR) + u) // (2 * u))
    return 0 if abs(p) >= 10**40 else p


def candidates(T: bytes, earlier: list) -> list:
    C = T.count(b"\0")
    return [R for R in reversed(earlier) if len(R["numbers"]) == C][:8] + [F for F in families() if len(F["numbers"]) == C]


def decode_template(rc, P, T: bytes, is_asf: bool, R) -> dict:
    count = T.count(b"\0")
    companions = {}
    if is_asf and R is not None:
        for match in DIRECTION.finditer(T):
            i = T.count(b"\0", 0, match.start())
            sizes = [abs(R["numbers"][j]["m"]) * Fraction(10) ** scale(R["numbers"][j]) for j in (i, i + 1, i + 2)]
            derived = i + sizes.index(max(sizes))
            companions[derived] = [j for j in (i, i + 1, i + 2) if j != derived]
    order = [i for i in range(count) if i not in companions]
    for derived, (_, later) in companions.items():
        order.insert(order.index(later) + 1, derived)
    numbers, hints, previous = [None] * count, [0] * count, None
    for i in order:
        S = R["numbers"][i] if R is not None else previous
        sci = rc.bit(P["scientific"], 0 if S is None else 1 + (S["letter"] != ""))
        d = read_int(rc, P["decimals"]) + (S["d"] if S else 0)
        if not 0 <= d <= 30:
            raise ValueError(f"skeleton number {i}: {d} decimals")
        n = {"d": d, "letter": "", "x": 0, "plus": False, "w": 0}
        if sci:
            n["letter"] = "E" if rc.bit(P["capital"], 1 if S and S["letter"] == "E" else 0) else "e"
            n["x"] = read_int(rc, P["exponent"]) + (S["x"] if S else 0)
            n["plus"] = n["x"] > 0 if n["x"] != 0 else bool(rc.bit(P["plus"], 0))
            n["w"] = read_int(rc, P["width"]) + (S["w"] if S and S["letter"] else 2)
            if not len(str(abs(n["x"]))) <= n["w"] <= 3:
                raise ValueError(f"skeleton number {i}: exponent {n['x']} in {n['w']} digits")
        hint = R["hints"][i] if R is not None else UNKNOWN
        residual = read_int(rc, P["mantissa"][(hint > 0) + (hint > 12) + (hint > 136)])
        n["m"] = residual + prediction(i, n, numbers, R, companions)
        if abs(n["m"]) >= 10**40:
            raise ValueError(f"skeleton number {i}: over 40 digits")
        n["negative"] = bool(rc.bit(P["negative_zero"], 0)) if n["m"] == 0 else n["m"] < 0
        numbers[i], hints[i], previous = n, abs(residual).bit_length(), n
    return {"template": T, "numbers": numbers, "hints": hints}


def packed(data: bytes) -> list:
    reader = Reader(data, "skeletons")
    lengths = [reader.varint() for _ in range(reader.varint())]
    files = [reader.take(n) for n in lengths]
    reader.end()
    return files


def read_skeletons(data: bytes, meta: dict) -> list:
    """The files of a format-10 `skeletons` stream, as bytes."""
    is_asf = [entry.get("format") != "bvh" for entry in meta["skeletons"]]
    if not data or data[0] not in (0, 1):
        raise ValueError("skeletons: unknown layout")
    if data[0] == 0:
        files = packed(zstd_stream(data[1:], dictionary("asf.txt")))
    else:
        reader = Reader(data[1:], "skeletons")
        frame = reader.take(reader.varint())
        templates = packed(zstd_stream(frame, templated(dictionary("asf.txt"))[0]))
        if len(templates) != len(is_asf) or sum(T.count(b"\0") for T in templates) > 1 << 18:
            raise ValueError("skeletons: not as many as meta lists, or over 2^18 numbers")
        rc = RangeDecoder(reader.rest(), 4)
        P = {"scientific": [1024] * 3, "capital": [1024] * 2, "plus": [1024], "negative_zero": [1024],
             "decimals": [1024] * 138, "exponent": [1024] * 138, "width": [1024] * 138, "reference": [1024] * 138,
             "mantissa": [[1024] * 138 for _ in range(4)]}
        earlier, files = [], []
        for T, asf in zip(templates, is_asf):
            options, R = candidates(T, earlier), None
            if options:
                choice = read_int(rc, P["reference"])
                if not 0 <= choice < len(options):
                    raise ValueError("skeletons: no such reference")
                R = options[choice]
            coded = decode_template(rc, P, T, asf, R)
            earlier.append(coded)
            pieces = T.split(b"\0")
            files.append(pieces[0] + b"".join(printed(n) + piece for n, piece in zip(coded["numbers"], pieces[1:])))
        rc.finish()
    if len(files) != len(is_asf) or sum(map(len, files)) > 1 << 28:
        raise ValueError("skeletons: not as many as meta lists, or too long")
    return files
