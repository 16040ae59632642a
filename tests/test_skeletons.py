"""Format 10's `skeletons` stream: every file back byte for byte, its numbers predicted and cheap."""

from __future__ import annotations

import hashlib

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mocapzip.archive import skeletons
from mocapzip.archive.skeletons import (TEMPLATES_AND_NUMBERS, WHOLE_TEXTS, decode_skeletons, encode_skeletons,
                                        join_numbers, split_numbers)
from mocapzip.codec.entropy.rangecoder import Decoder, Encoder, new_models
from mocapzip.formats.bvh import read_hierarchy
from reference_decoder.skeletons import read_skeletons as reference_read

LIMIT = 1 << 28


def round_trip(texts: list[bytes], is_asf: list[bool]) -> bytes:
    coded = encode_skeletons(texts, is_asf)
    assert decode_skeletons(coded, is_asf, LIMIT) == texts
    meta = {"skeletons": [{"name": "x"} if asf else {"name": "x", "format": "bvh"} for asf in is_asf]}
    assert reference_read(coded, meta) == texts  # the spec's decoder agrees
    return coded


def shared_skeletons(shared_data) -> tuple[list[bytes], list[bool]]:
    """Every ASF in the shared data, then every distinct BVH hierarchy."""
    asfs = [p.read_bytes() for p in sorted(shared_data.glob("**/*.asf"))]
    hierarchies = {}
    for path in sorted(shared_data.glob("**/*.bvh")):
        text, encoding = read_hierarchy(path)
        hierarchies.setdefault(text.encode(encoding), None)
    return asfs + list(hierarchies), [True] * len(asfs) + [False] * len(hierarchies)


def test_every_shared_skeleton_comes_back_byte_for_byte(shared_data):
    texts, is_asf = shared_skeletons(shared_data)
    assert sum(is_asf) >= 19 and len(texts) - sum(is_asf) >= 6
    assert round_trip(texts, is_asf)[0] == TEMPLATES_AND_NUMBERS
    for text, asf in zip(texts, is_asf):
        assert join_numbers(*split_numbers(text)) == text
        round_trip([text], [asf])


def test_cmu_skeletons_cost_what_issue_17_asks(shared_data):
    """600 B or less for an archive's first CMU skeleton, 300 B or less for each after it
    (measured: 288-370 B, and 3,340 B for all 13; format 9 took 534-622 and 5,552)."""
    texts = [p.read_bytes() for p in sorted(shared_data.glob("cmu/*/*.asf"))]
    assert len(texts) == 13
    firsts = [len(round_trip([text], [True])) for text in texts]
    all_13 = len(round_trip(texts, [True] * 13))
    assert max(firsts) <= 600 and (all_13 - firsts[0]) / 12 <= 300, (firsts, all_13)


def test_the_unit_vector_prediction_is_what_pays():
    """A direction's largest component, predicted from the other two, costs almost nothing: off the
    unit sphere, or not predicted (not an ASF), it costs more."""
    base = b"begin\n  direction 0.600000 -0.480000 0.640000\n  length 2.5\nend\n"
    exact = b"begin\n  direction 0.480000 -0.360000 0.800000\n  length 2.1\nend\n"
    off = b"begin\n  direction 0.480000 -0.360000 0.812345\n  length 2.1\nend\n"
    assert len(round_trip([base, exact], [True, True])) < len(round_trip([base, off], [True, True]))
    assert len(round_trip([base, exact], [True, True])) < len(round_trip([base, exact], [False, False]))


@pytest.mark.parametrize("number", [b"0", b"-0", b"-0.0", b"1.0", b"12.3400", b"0.000001", b"7.62852e-016",
                                    b"1.53589e-011", b"-4.2195E+05", b"1e+0", b"1e-0", b"-0e+000", b"123456789012",
                                    b"9" * 40, b"0." + b"0" * 29 + b"1", b"1.5e-999", b"2.5e+999"])
def test_a_number_prints_as_it_was_read(number):
    template, numbers = split_numbers(b"x " + number + b" y")
    assert template == b"x \0 y" and len(numbers) == 1
    assert join_numbers(template, numbers) == b"x " + number + b" y"
    round_trip([b"x " + number + b" y", b"x " + number + b" y"], [True, False])


@pytest.mark.parametrize("text, count", [(b"007", 0), (b".5", 0), (b"5.", 0), (b"1e5", 0), (b"1e+1234", 1), (b"x1", 0),
                                         (b"1x", 0), (b"1.2.3", 0), (b"a_1", 0), (b"+1", 1), (b"9" * 41, 0),
                                         (b"0." + b"0" * 31, 0), (b"(-160.0 20.0)", 2)])
def test_what_is_not_a_number_stays_text(text, count):
    template, numbers = split_numbers(b" " + text + b" ")
    assert len(numbers) == count == template.count(b"\0")
    assert join_numbers(template, numbers) == b" " + text + b" "


TOKENS = st.one_of(st.sampled_from([" ", "\n", "\r\n", "(", ")", "direction", "length", "x", "-", ".", "e", "_"]),
                   st.from_regex(r"-?(0|[1-9][0-9]{0,12})(\.[0-9]{1,9})?([eE][-+][0-9]{1,3})?", fullmatch=True))


@settings(max_examples=150, deadline=None)
@given(st.lists(st.lists(TOKENS, max_size=40).map("".join).map(str.encode), min_size=1, max_size=4),
       st.lists(st.booleans(), min_size=4, max_size=4))
def test_any_text_comes_back(texts, is_asf):
    round_trip(texts, is_asf[:len(texts)])


def test_integers_of_every_length_come_back():
    """The compiled decode of `_put_int`'s code (`Decoder.exp_golomb`), across its 32-bit chunks."""
    values = [0, 1, -1, 2, -3, 2**31, -(2**32 + 5), 2**63 + 1, -(2**64), 3**85, -(2**135 + 2**70 + 1)]
    encoder, models = Encoder(), new_models(2 + skeletons._BIT_LENGTHS)
    for value in values:
        skeletons._put_int(encoder, models, value)
    stream = encoder.finish()
    decoder, models = Decoder(stream), new_models(2 + skeletons._BIT_LENGTHS)
    assert [skeletons._get_int(decoder, models) for _ in values] == values
    decoder.finish()
    decoder, models = Decoder(stream[:len(stream) // 2]), new_models(2 + skeletons._BIT_LENGTHS)
    with pytest.raises(ValueError, match="ends early"):
        [skeletons._get_int(decoder, models) for _ in values]


def test_texts_that_cannot_be_templates_are_stored_whole(monkeypatch):
    assert encode_skeletons([b"a \0 1.5"], [True])[0] == WHOLE_TEXTS  # a NUL: no template can hold it
    monkeypatch.setattr(skeletons, "MAX_NUMBERS", 3)
    text = b"1.25 -3.5 7.75 2.125"
    coded = encode_skeletons([text], [True])
    assert coded[0] == WHOLE_TEXTS and decode_skeletons(coded, [True], LIMIT) == [text]


def test_damaged_streams_are_refused(shared_data):
    texts = [p.read_bytes() for p in sorted(shared_data.glob("cmu/*/*.asf"))][:2]
    coded = encode_skeletons(texts, [True, True])
    assert coded[0] == TEMPLATES_AND_NUMBERS
    for damaged, message in ((b"\x02" + coded[1:], "unknown skeletons layout 2"),
                             (coded[:-2], "range-coded stream"),
                             (coded + b"\0", "unexpected bytes|inconsistent")):
        with pytest.raises(ValueError, match=message):
            decode_skeletons(damaged, [True, True], LIMIT)
    with pytest.raises(ValueError, match="2 skeleton texts, but meta lists 3"):
        decode_skeletons(coded, [True, True, True], LIMIT)
    limit = sum(len(split_numbers(text)[0]) for text in texts) + 10  # the templates fit, the texts do not
    with pytest.raises(ValueError, match=f"skeleton texts of more than {limit:,} bytes"):
        decode_skeletons(coded, [True, True], limit)


def test_the_templated_dictionary_is_the_one_the_spec_names():
    """Format 10's templates are coded against `asf.txt` with its numbers set to NUL: a change to
    the number pattern would change it, and every layout-1 stream with it (docs/format.md)."""
    data = skeletons.template_dictionary()
    assert (len(data), data.count(b"\0")) == (17_014, 1_083)
    assert hashlib.sha256(data).hexdigest() == "4600ef074e3bc1f5c547c87f6b16327df8557ef85d596f4c275f6b962bd37a27"


def test_a_reference_beyond_the_candidates_is_refused(monkeypatch):
    """The encoder names its reference among the candidates; a stream naming one the decoder does
    not have is damaged."""
    first = np.random.default_rng(7).uniform(-9, 9, 40)
    texts = [" ".join(f"{v:.6f}" for v in values).encode() for values in (first, [v + 1e-6 for v in first])]
    real = skeletons._candidates

    def more(template, earlier):  # two bad candidates before the real one: the encoder takes the third
        found = real(template, earlier)
        bad = [skeletons._Reference(template, (skeletons.Number(-999_999, 1),) * 40, (0,) * 40)] * 2
        return bad + found if found else found

    monkeypatch.setattr(skeletons, "_candidates", more)
    coded = encode_skeletons(texts, [True, True])
    assert coded[0] == TEMPLATES_AND_NUMBERS and decode_skeletons(coded, [True, True], LIMIT) == texts
    monkeypatch.undo()
    with pytest.raises(ValueError, match="skeleton 1: reference 2 of 1"):
        decode_skeletons(coded, [True, True], LIMIT)


def test_a_direction_in_tens_predicts_its_component_as_zero():
    """Found in review: every scale 10 or coarser made the unit-vector prediction take a float
    square root and crash; a unit vector's component rounds to 0 there."""
    texts = [b"begin\n  direction 0e+1 0e+1 1e+1\nend\n", b"begin\n  direction 0e+1 1e+1 0e+1\nend\n"]
    round_trip(texts, [True, True])


def test_a_skeleton_looks_at_no_more_earlier_ones_than_it_may_choose():
    """Found in review: the candidates scanned every earlier skeleton (quadratic in a crafted
    archive of many); they stop at the latest CANDIDATES_EARLIER with as many numbers. Counted by
    the earlier skeletons looked at, not by a clock."""

    class Counting(list):
        seen = 0

        def __reversed__(self):
            for item in super().__reversed__():
                self.seen += 1
                yield item

    template = b"\0 \0"
    earlier = Counting(skeletons._Reference(template, (skeletons.Number(k, 0),) * 2, (0, 0)) for k in range(3000))
    found = skeletons._candidates(template, earlier)
    assert [r.numbers[0].mantissa for r in found] == list(range(2999, 2999 - skeletons.CANDIDATES_EARLIER, -1))
    assert earlier.seen <= skeletons.CANDIDATES_EARLIER + 1


def test_directions_are_found_on_every_line():
    template = split_numbers(b"begin\n  direction 0.5 0.5 0.707107\n  length 2\nend\n" * 2000)[0]
    assert skeletons._directions(template) == list(range(0, 8000, 4))
