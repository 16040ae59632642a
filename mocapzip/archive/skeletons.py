"""The `skeletons` stream of format 10: the text between numbers by zstd, the numbers by prediction.

Why: an ASF is given back byte for byte, and after format 7's dictionary what a CMU skeleton
still cost (about 415 B after the archive's first) was its numbers: about 100 of them differ
between two subjects, and zstd spends about 4 bits on each printed digit. Here every number is
predicted from the same number in a reference (the archive's last earlier skeleton like it, else
the family's means, `dictionaries/asf_means.txt`), and an ASF bone's direction, a
unit vector, gives its largest component from the other two. Only the residuals are coded, by
the binary range coder's adaptive models; the text around the numbers, with each number a NUL
byte, goes to zstd with the dictionary made the same way. docs/format.md ("`skeletons`
(format 10 on)") is the byte-level specification.

A number is a token `-?(0|[1-9][0-9]*)(\\.[0-9]+)?([eE][-+][0-9]{1,3})?` that no letter, digit,
`_` or `.` touches, with at most 40 digits and 30 decimals; anything else stays in the text.
Printed as it was: sign, digits, decimals, exponent letter, sign and width are all kept.
"""

from __future__ import annotations

import functools
import itertools
import math
import re
from dataclasses import dataclass
from fractions import Fraction

from mocapzip.archive.dictionaries import dictionary
from mocapzip.codec.entropy.rangecoder import Decoder, Encoder, new_models
from mocapzip.codec.entropy.zstd import ByteReader, decode_bytes, encode_bytes, pack_blobs, unpack_blobs, write_varint

__all__ = ["encode_skeletons", "decode_skeletons", "template_dictionary"]

PLACEHOLDER = b"\0"
WHOLE_TEXTS, TEMPLATES_AND_NUMBERS = 0, 1  # the stream's first byte
NUMBER = re.compile(rb"(?<![A-Za-z0-9_.])(-?)(0|[1-9][0-9]*)(?:\.([0-9]+))?(?:([eE])([-+])([0-9]{1,3}))?(?![A-Za-z0-9_.])")
DIRECTION = re.compile(rb"(?m)^[ \t]*direction[ \t]+\0[ \t]+\0[ \t]+\0[ \t\r]*$")
SECTION = re.compile(rb"(?m)^# AST/ASF file generated")
MAX_DIGITS = 40
MAX_DECIMALS = 30
# In all of a stream's templates. A number the stream holds in a few bits decodes in about 8 us, so
# at most about 2 s; one of 40 digits takes about 54 us, but also its 17 bytes of the stream.
MAX_NUMBERS = 1 << 18
MAX_SCALE_GAP = 30  # a reference more than this many decimal places away predicts 0
CANDIDATES_EARLIER = 8  # earlier skeletons a skeleton may be predicted from
_LARGEST = 10**MAX_DIGITS  # a prediction this large or larger is 0 instead
_BIT_LENGTHS = 136  # |residual| < 2 x 10**40 < 2**136
_UNKNOWN = _BIT_LENGTHS + 1
_HINT_LIMITS = (0, 12, _BIT_LENGTHS)  # a residual's context: its reference's took 0, 1-12, 13-136 bits, or unknown


@dataclass(frozen=True)
class Number:
    """A printed number: `mantissa` x 10**`scale`, and how it was printed. The mantissa is
    signed; `negative` keeps the sign of a zero (`-0.0`)."""

    mantissa: int
    decimals: int
    negative: bool = False
    letter: str = ""  # "", "e" or "E"
    exponent: int = 0
    exponent_plus: bool = False
    exponent_width: int = 0

    @property
    def scale(self) -> int:
        return self.exponent - self.decimals

    def text(self) -> bytes:
        digits = str(abs(self.mantissa)).rjust(self.decimals + 1, "0")
        out = "-" if self.negative else ""
        out += digits if not self.decimals else f"{digits[:-self.decimals]}.{digits[-self.decimals:]}"
        if self.letter:
            sign = "+" if self.exponent_plus else "-"
            out += f"{self.letter}{sign}{str(abs(self.exponent)).rjust(self.exponent_width, '0')}"
        return out.encode()


def _number(match: re.Match) -> Number | None:
    minus, whole, fraction, letter, sign, power = match.groups()
    fraction = fraction or b""
    if len(whole) + len(fraction) > MAX_DIGITS or len(fraction) > MAX_DECIMALS:
        return None
    negative = minus == b"-"
    magnitude = int(whole + fraction)
    exponent = int(sign + power) if letter else 0
    return Number(-magnitude if negative else magnitude, len(fraction), negative, (letter or b"").decode(),
                  exponent, sign == b"+", len(power) if letter else 0)


def split_numbers(text: bytes) -> tuple[bytes, list[Number]]:
    """`text` with each number a NUL byte, and the numbers in order."""
    numbers, pieces, start = [], [], 0
    for match in NUMBER.finditer(text):
        number = _number(match)
        if number is None:
            continue
        pieces += [text[start:match.start()], PLACEHOLDER]
        numbers.append(number)
        start = match.end()
    pieces.append(text[start:])
    return b"".join(pieces), numbers


def join_numbers(template: bytes, numbers: list[Number]) -> bytes:
    pieces = template.split(PLACEHOLDER)
    out = [pieces[0]]
    for number, piece in zip(numbers, pieces[1:]):
        out += [number.text(), piece]
    return b"".join(out)


@functools.cache
def template_dictionary() -> bytes:
    """`asf.txt` as templates: what the `skeletons` stream's zstd frame refers back to."""
    return split_numbers(dictionary("asf.txt"))[0]


def _sections(name: str) -> list[tuple[bytes, list[Number]]]:
    text = dictionary(name)
    starts = [m.start() for m in SECTION.finditer(text)] + [len(text)]
    return [split_numbers(text[a:b]) for a, b in zip(starts, starts[1:])]


@functools.cache
def _family_references() -> tuple[_Reference, ...]:
    """Each family of `asf.txt` (a section per `# AST/ASF file generated` line): its template,
    and its numbers as `asf_means.txt` prints them (the family's mean where `asf.txt` has 0, as no
    two members agree), hinted unknown where the two files differ. What a skeleton no earlier one
    in the archive resembles is predicted from."""
    references = []
    for (template, shared), (same, means) in zip(_sections("asf.txt"), _sections("asf_means.txt"), strict=True):
        if same != template:
            raise RuntimeError("mocapzip is damaged: asf.txt and asf_means.txt differ between their numbers")
        hints = tuple(0 if a.text() == b.text() else _UNKNOWN for a, b in zip(shared, means))
        references.append(_Reference(template, tuple(means), hints))
    return tuple(references)


def _directions(template: bytes) -> list[int]:
    """Index of the first number of each ASF `direction` line whose three values are numbers."""
    firsts, counted, before = [], 0, 0
    for match in DIRECTION.finditer(template):
        before += template.count(PLACEHOLDER, counted, match.start())
        counted = match.start()
        firsts.append(before)
    return firsts


@dataclass(frozen=True)
class _Reference:
    """What a skeleton's numbers are predicted from: another skeleton's template and numbers, and
    for each number how many bits its own residual took (`_UNKNOWN` where a family template
    left the value out)."""

    template: bytes
    numbers: tuple[Number, ...]
    hints: tuple[int, ...]


def _candidates(template: bytes, earlier: list[_Reference]) -> list[_Reference]:
    """What a skeleton may be predicted from, for the encoder to choose: the latest
    CANDIDATES_EARLIER earlier skeletons with as many numbers (latest first), then the families
    of `asf_means.txt` with as many (HDM05's template is also CMU's with CRLF line ends)."""
    count = template.count(PLACEHOLDER)
    alike = itertools.islice((coded for coded in reversed(earlier) if len(coded.numbers) == count), CANDIDATES_EARLIER)
    return [*alike, *(family for family in _family_references() if len(family.numbers) == count)]


def _context(hint: int) -> int:
    low, middle, high = _HINT_LIMITS  # unrolled: this runs for every number
    return (hint > low) + (hint > middle) + (hint > high)


def _scaled(mantissa: int, from_scale: int, to_scale: int) -> int:
    """`mantissa` x 10**from_scale in units of 10**to_scale, rounded half away from zero; 0 if
    the two are more than MAX_SCALE_GAP places apart."""
    gap = from_scale - to_scale
    if abs(gap) > MAX_SCALE_GAP:
        return 0
    if gap >= 0:
        scaled = mantissa * 10**gap
    else:
        unit = 10**-gap
        scaled = (2 * abs(mantissa) + unit) // (2 * unit) * (-1 if mantissa < 0 else 1)
    return scaled if abs(scaled) < _LARGEST else 0


def _unit_component(others: list[Number], own: Number, sign_from: Number) -> int:
    """The mantissa, at `own`'s scale, that makes a unit vector with `others` (0 if they are
    longer than 1 already), signed as `sign_from`: exact integer arithmetic. Where every scale
    is 10 or coarser, a unit vector's component rounds to 0."""
    finest = min(own.scale, *(n.scale for n in others))
    if finest > 0 or own.scale - finest > MAX_SCALE_GAP or any(n.scale - finest > MAX_SCALE_GAP for n in others):
        return 0
    rest = 10 ** (-2 * finest) - sum((n.mantissa * 10 ** (n.scale - finest)) ** 2 for n in others)
    root = math.isqrt(rest) if rest > 0 else 0
    unit = 10 ** (own.scale - finest)
    magnitude = (2 * root + unit) // (2 * unit)
    if magnitude >= _LARGEST:
        return 0
    return -magnitude if sign_from.mantissa < 0 or sign_from.negative else magnitude


class _Models:
    """The adaptive models of one stream: a bit per kind of flag, and an Exp-Golomb code per
    kind of integer (is it 0, its sign, its bit length in unary, then its lower bits direct)."""

    FLAGS = {"scientific": 3, "negative_zero": 1, "capital": 2, "plus": 1}
    INTEGERS = ("decimals", "exponent", "width", "reference")

    def __init__(self):
        self.flags = {name: new_models(n) for name, n in self.FLAGS.items()}
        self.integers = {name: new_models(2 + _BIT_LENGTHS) for name in self.INTEGERS}
        self.mantissas = [new_models(2 + _BIT_LENGTHS) for _ in range(len(_HINT_LIMITS) + 1)]


def _put_int(encoder: Encoder, models, value: int) -> None:
    encoder.bit(models, 0, int(value != 0))
    if value == 0:
        return
    encoder.bit(models, 1, int(value < 0))
    length = abs(value).bit_length()  # at most _BIT_LENGTHS: numbers and predictions are under 10**40
    for k in range(1, length):
        encoder.bit(models, 1 + k, 1)
    if length < _BIT_LENGTHS:
        encoder.bit(models, 1 + length, 0)
    rest, bits = abs(value) - (1 << (length - 1)), length - 1
    while bits > 0:
        take = min(bits, 32)
        bits -= take
        encoder.direct((rest >> bits) & ((1 << take) - 1), take)


def _get_int(decoder: Decoder, models) -> int:
    return decoder.exp_golomb(models, _BIT_LENGTHS)


class _Coder:
    """Codes one skeleton's numbers against its reference. The encoder and the decoder run the
    same steps: each field is predicted from the reference and from what came before."""

    def __init__(self, template: bytes, is_asf: bool, reference: _Reference | None, models: _Models):
        self.models, self.reference, self.template = models, reference, template
        self.count = template.count(PLACEHOLDER)
        self.numbers: list[Number | None] = [None] * self.count
        self.hints = [0] * self.count
        self.last: Number | None = None
        # In each ASF direction, the component largest in the reference is coded after the other
        # two and predicted from them: index -> the other two.
        self.derived: dict[int, tuple[int, int]] = {}
        if is_asf and reference is not None:
            for first in _directions(template):
                three = reference.numbers[first:first + 3]
                sizes = [abs(n.mantissa) * Fraction(10) ** n.scale for n in three]
                largest = first + sizes.index(max(sizes))
                self.derived[largest] = tuple(first + k for k in range(3) if first + k != largest)
        after = {later: i for i, (_, later) in self.derived.items()}
        self.order = []
        for i in range(self.count):
            if i not in self.derived:
                self.order += [i, after[i]] if i in after else [i]

    def cost(self, numbers: list[Number]) -> int:
        """About how many bits coding `numbers` against this reference takes: what the encoder
        chooses a reference by (the models' state left aside)."""
        bits = 0
        for i in self.order:
            self.numbers[i] = numbers[i]
            ref = self._shape_reference(i)
            bits += abs(numbers[i].mantissa - self._predicted(i, numbers[i])).bit_length()
            bits += 8 * (ref is None or (ref.decimals, ref.letter) != (numbers[i].decimals, numbers[i].letter))
        return bits

    def coded(self) -> _Reference:
        return _Reference(self.template, tuple(self.numbers), tuple(self.hints))

    def _predicted(self, i: int, shape: Number) -> int:
        if self.reference is None:
            return 0
        ref = self.reference.numbers[i]
        if i in self.derived:
            return _unit_component([self.numbers[j] for j in self.derived[i]], shape, ref)
        return _scaled(ref.mantissa, ref.scale, shape.scale)

    def _mantissa_models(self, i: int):
        return self.models.mantissas[_context(self.reference.hints[i] if self.reference else _UNKNOWN)]

    def _shape_reference(self, i: int) -> Number | None:
        """What the way number `i` is printed is predicted from: its reference, else the number
        coded before it."""
        return self.reference.numbers[i] if self.reference else self.last

    def put(self, encoder: Encoder, i: int, number: Number) -> None:
        m, ref = self.models, self._shape_reference(i)
        scientific = bool(number.letter)
        encoder.bit(m.flags["scientific"], 0 if ref is None else 1 + bool(ref.letter), int(scientific))
        _put_int(encoder, m.integers["decimals"], number.decimals - (ref.decimals if ref else 0))
        if scientific:
            encoder.bit(m.flags["capital"], int(bool(ref) and ref.letter == "E"), int(number.letter == "E"))
            _put_int(encoder, m.integers["exponent"], number.exponent - (ref.exponent if ref else 0))
            if number.exponent == 0:
                encoder.bit(m.flags["plus"], 0, int(number.exponent_plus))
            _put_int(encoder, m.integers["width"], number.exponent_width - (ref.exponent_width if ref and ref.letter else 2))
        residual = number.mantissa - self._predicted(i, number)
        _put_int(encoder, self._mantissa_models(i), residual)
        if number.mantissa == 0:
            encoder.bit(m.flags["negative_zero"], 0, int(number.negative))
        self.numbers[i], self.hints[i], self.last = number, abs(residual).bit_length(), number

    def get(self, decoder: Decoder, i: int) -> None:
        m, ref = self.models, self._shape_reference(i)
        scientific = decoder.bit(m.flags["scientific"], 0 if ref is None else 1 + bool(ref.letter))
        decimals = _get_int(decoder, m.integers["decimals"]) + (ref.decimals if ref else 0)
        letter, exponent, plus, width = "", 0, False, 0
        if scientific:
            letter = "E" if decoder.bit(m.flags["capital"], int(bool(ref) and ref.letter == "E")) else "e"
            exponent = _get_int(decoder, m.integers["exponent"]) + (ref.exponent if ref else 0)
            plus = exponent > 0 if exponent else bool(decoder.bit(m.flags["plus"], 0))
            width = _get_int(decoder, m.integers["width"]) + (ref.exponent_width if ref and ref.letter else 2)
            if not len(str(abs(exponent))) <= width <= 3:  # also refuses exponents of over 3 digits
                raise ValueError(f"skeleton number {i}: exponent {exponent} in {width} digits")
        if not 0 <= decimals <= MAX_DECIMALS:
            raise ValueError(f"skeleton number {i}: {decimals} decimals (at most {MAX_DECIMALS})")
        residual = _get_int(decoder, self._mantissa_models(i))
        mantissa = residual + self._predicted(i, Number(0, decimals, False, letter, exponent, plus, width))
        if abs(mantissa) >= _LARGEST:
            raise ValueError(f"skeleton number {i}: more than {MAX_DIGITS} digits")
        negative = mantissa < 0 or (mantissa == 0 and bool(decoder.bit(m.flags["negative_zero"], 0)))
        self.numbers[i] = self.last = Number(mantissa, decimals, negative, letter, exponent, plus, width)
        self.hints[i] = abs(residual).bit_length()


def encode_skeletons(texts: list[bytes], is_asf: list[bool]) -> bytes:
    """The `skeletons` stream of `texts` (ASF files, and BVH hierarchies where `is_asf` is false),
    its first byte saying how: as templates and numbers, or as the texts themselves. The texts
    themselves where that is smaller (numbers with no reference can cost more than zstd's repeats
    of them), where a text holds a NUL byte, or where they hold over MAX_NUMBERS numbers."""
    whole = bytes([WHOLE_TEXTS]) + encode_bytes(pack_blobs(texts), dictionary("asf.txt"))
    if any(PLACEHOLDER in text for text in texts):  # a NUL would read as a number's place
        return whole
    split = [split_numbers(text) for text in texts]
    if sum(len(numbers) for _, numbers in split) > MAX_NUMBERS:
        return whole
    frame = encode_bytes(pack_blobs(template for template, _ in split), template_dictionary())
    encoder, models, done = Encoder(), _Models(), []
    for (template, numbers), asf in zip(split, is_asf):
        candidates, reference = _candidates(template, done), None
        if candidates:
            costs = [_Coder(template, asf, candidate, models).cost(numbers) for candidate in candidates]
            choice = costs.index(min(costs))
            _put_int(encoder, models.integers["reference"], choice)
            reference = candidates[choice]
        coder = _Coder(template, asf, reference, models)
        for i in coder.order:
            coder.put(encoder, i, numbers[i])
        done.append(coder.coded())
    predicted = bytearray([TEMPLATES_AND_NUMBERS])
    write_varint(predicted, len(frame))
    predicted = bytes(predicted) + frame + encoder.finish()
    return predicted if len(predicted) <= len(whole) else whole


def decode_skeletons(blob: bytes, is_asf: list[bool], limit: int) -> list[bytes]:
    """Inverse of `encode_skeletons`; ValueError on anything inconsistent, and on texts that
    would come to more than `limit` bytes in all."""
    reader = ByteReader(bytes(blob))
    layout = reader.byte()
    if layout == TEMPLATES_AND_NUMBERS:
        return _predicted_texts(reader, is_asf, limit)
    if layout != WHOLE_TEXTS:
        raise ValueError(f"unknown skeletons layout {layout}")
    texts = unpack_blobs(decode_bytes(reader.take(reader.remaining()), limit, dictionary("asf.txt")))
    _check_count(texts, is_asf)
    return texts


def _check_count(texts: list[bytes], is_asf: list[bool]) -> None:
    if len(texts) != len(is_asf):
        raise ValueError(f"{len(texts)} skeleton texts, but meta lists {len(is_asf)}")


def _predicted_texts(reader: ByteReader, is_asf: list[bool], limit: int) -> list[bytes]:
    templates = unpack_blobs(decode_bytes(reader.take(reader.varint()), limit, template_dictionary()))
    _check_count(templates, is_asf)
    count = sum(template.count(PLACEHOLDER) for template in templates)
    if count > MAX_NUMBERS:
        raise ValueError(f"{count:,} skeleton numbers (at most {MAX_NUMBERS:,})")
    decoder, models, texts, done, size = Decoder(reader.take(reader.remaining())), _Models(), [], [], 0
    for template, asf in zip(templates, is_asf):
        candidates, reference = _candidates(template, done), None
        if candidates:
            choice = _get_int(decoder, models.integers["reference"])
            if not 0 <= choice < len(candidates):
                raise ValueError(f"skeleton {len(texts)}: reference {choice} of {len(candidates)}")
            reference = candidates[choice]
        coder = _Coder(template, asf, reference, models)
        for i in coder.order:
            coder.get(decoder, i)
        text = join_numbers(template, coder.numbers)
        size += len(text)
        if size > limit:
            raise ValueError(f"skeleton texts of more than {limit:,} bytes")
        texts.append(text)
        done.append(coder.coded())
    decoder.finish()
    return texts
