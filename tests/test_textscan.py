"""The number scanner of the text readers (readers/textscan.py) reads what Python's ``float`` reads, bit for
bit: on every AMC and BVH text of ../shared/data, on seeded fuzzed spellings, at the end of a buffer, and
through the motion-line kernel's two paths (a line's tokens found by bit masks first; any other line token
after token)."""
import re

import numpy as np
import pytest

from conftest import DATA, SAMPLE_86_09, SAMPLE_86_ASF, shared_cases
from naive_kinematics import naive_amc_values
from mocapdb.errors import ParseError
from mocapdb.readers import find_skeleton, load_skeleton
from mocapdb.readers.amc import parse_amc
from mocapdb.readers.bvh import parse_bvh
from mocapdb.readers.sources import read_bytes
from mocapdb.readers.textscan import NUM_BAD, NUM_OK, NUM_SLOW, parse_numbers, parse_rows

ALL_AMC = sorted(DATA.glob("**/*.amc"))
ALL_BVH = sorted([*DATA.glob("**/*.bvh"), *DATA.glob("**/*.bvh.gz")])


def _float_or_none(tok: bytes):
    try:
        return float(tok)
    except ValueError:
        return None


def _same_bits(a, b) -> bool:
    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    return a.shape == b.shape and np.array_equal(a.view(np.int64), b.view(np.int64))


def _naive_motion_lines(data: bytes) -> np.ndarray:
    """The BVH motion lines after ``Frame Time:`` read with ``float`` (a token ``float`` refuses, or a
    non-finite one, as NaN: lost tracking, as the reader reads it)."""
    data = data[3:] if data.startswith(b"\xef\xbb\xbf") else data
    if b"\n" not in data:
        data = data.replace(b"\r", b"\n")
    m = re.search(rb"Frame\s+Time\s*:[^\n]*\n", data, re.IGNORECASE)
    rows = []
    for line in data[m.end():].split(b"\n"):
        tok = line.split()
        if tok:
            vals = [_float_or_none(t) for t in tok]
            rows.append([v if v is not None and np.isfinite(v) else np.nan for v in vals])
    return np.array(rows, dtype=np.float64)


@pytest.mark.slow
@pytest.mark.shared
@pytest.mark.parametrize("path", shared_cases(ALL_AMC + ALL_BVH), ids=lambda p: str(p.relative_to(DATA)))
def test_every_shared_text_reads_as_float_reads_it(path):
    data = read_bytes(path)
    if ".amc" in path.name:
        skeleton = load_skeleton(find_skeleton(path) or DATA / "cmu/02/02.asf")   # cmu/13, cmu/14: any CMU ASF
        m = parse_amc(data, skeleton)
        frames, _, _ = naive_amc_values(data, skeleton)
        assert m.n_frames == len(frames)
        for name, sl in m.columns.items():
            assert _same_bits(m.values[:, sl], [fr[name] for fr in frames]), name
        return
    values = parse_bvh(data, path=path).values
    ref = _naive_motion_lines(data)
    nan = np.isnan(ref)
    assert values.shape == ref.shape
    assert np.array_equal(np.isnan(values), nan)
    assert _same_bits(values[~nan], ref[~nan])


def _spelling(rng) -> bytes:
    """A random decimal spelling: sign, leading zeros, digits on either side of an optional point,
    an optional exponent (any case, signed, leading zeros), up to ~40 digits."""
    sign = rng.choice(["", "-", "+"])
    zeros = "0" * int(rng.integers(0, 4)) if rng.random() < 0.3 else ""
    whole = "".join(map(str, rng.integers(0, 10, int(rng.integers(0, 21)))))
    frac = "".join(map(str, rng.integers(0, 10, int(rng.integers(0, 21)))))
    t = zeros + whole
    if rng.random() < 0.8:
        t += "." + frac
    if rng.random() < 0.3:
        t += rng.choice(["e", "E"]) + rng.choice(["", "-", "+"]) + "0" * int(rng.integers(0, 2)) \
            + str(int(rng.integers(0, 400)))
    return (sign + t).encode()


def test_the_scanner_equals_float_on_fuzzed_spellings():
    rng = np.random.default_rng(35)
    toks = [_spelling(rng) for _ in range(30000)]
    # junk over the number alphabet: the scanner refuses exactly what float refuses
    alphabet = np.frombuffer(b"0123456789.+-eE", np.uint8)
    toks += [bytes(rng.choice(alphabet, int(rng.integers(1, 25)))) for _ in range(20000)]
    toks += [b"0", b"-0", b"+0", b"0.", b".0", b".5", b"5.", b"-.5", b"+5.", b"00000000000000000000001",
             b"0.000000000000000000001", b"12345678", b"123456789", b"1234567890123456789012345",
             b"9007199254740992", b"9007199254740993", b"-9007199254740993.0", b"1e22", b"1e23", b"1e-22",
             b"1e-23", b"4.9e-324", b"1.7976931348623157e308", b"1e999", b"2.72109e-026", b"1E+05", b"1e0005"]
    vals, st = parse_numbers(toks)
    ref = [_float_or_none(t) for t in toks]
    refused = np.array([r is None for r in ref])
    assert np.array_equal(st == NUM_BAD, refused)
    ok = st == NUM_OK
    assert ok.sum() > 10000 and (st == NUM_SLOW).sum() > 1000
    assert _same_bits(vals[ok], [r for r, k in zip(ref, ok) if k])


@pytest.mark.parametrize("newline", [b"", b"\n", b"\r\n"])
def test_tokens_at_the_end_of_the_text(newline):
    # the last number of a text that ends without a line end: every length and alignment, so the
    # scanner's word reads meet the end of the buffer at each byte of a word
    rng = np.random.default_rng(5)
    for _ in range(400):
        toks = [_spelling(rng) for _ in range(3)]
        if any(_float_or_none(t) is None or not np.isfinite(float(t)) for t in toks):
            continue
        pad = b" " * int(rng.integers(0, 9))
        text = pad + b" ".join(toks) + newline
        got = parse_rows(text, 0, 1, 3, "<fuzz>")
        assert _same_bits(got, [[float(t) for t in toks]]), text


def _table(rng, n_rows, n_cols):
    """Random motion lines (valid spellings of finite numbers), random blanks, line ends and blank lines."""
    values, lines = [], []
    for _ in range(n_rows):
        toks = []
        while len(toks) < n_cols:
            t = _spelling(rng)
            f = _float_or_none(t)
            if f is not None and np.isfinite(f):
                toks.append(t)
        values.append([float(t) for t in toks])
        seps = [rng.choice([b" ", b"\t", b"  ", b" \t"]) for _ in range(n_cols - 1)]
        line = b"".join(t + s for t, s in zip(toks, seps)) + toks[-1]
        line = rng.choice([b"", b" ", b"\t"]) + line + rng.choice([b"", b" ", b"\r"])
        lines.append(line)
        if rng.random() < 0.05:
            lines.append(rng.choice([b"", b"  ", b"\r"]))
    return values, b"\n".join(lines) + rng.choice([b"", b"\n"])


@pytest.mark.parametrize("n_cols", [1, 3, 7, 31, 96])
def test_motion_lines_read_as_float_reads_them(n_cols):
    rng = np.random.default_rng(n_cols)
    values, text = _table(rng, 60, n_cols)
    assert _same_bits(parse_rows(text, 0, 60, n_cols, "<fuzz>"), values)


@pytest.mark.parametrize("n_cols", [3, 62])
def test_a_bad_line_is_named_as_before(n_cols):
    # a line the bit masks cannot take (a control byte, a bad token, a wrong count) is read token after
    # token: the rows before it as float reads them, the error at its line, token and frame
    rng = np.random.default_rng(100 + n_cols)
    for case in range(30):
        values, text = _table(rng, 12, n_cols)
        lines = text.split(b"\n")
        k = int(rng.integers(0, len(lines)))
        while not lines[k].split():
            k = (k + 1) % len(lines)
        toks = lines[k].split()
        kind = case % 4
        if kind == 0:
            toks[int(rng.integers(0, len(toks)))] = b"1.5x"
        elif kind == 1:
            toks.append(b"7")
        elif kind == 2:
            toks = toks[:-1] or [b"\x01"]
        else:
            toks[int(rng.integers(0, len(toks)))] += b"\x01"
        lines[k] = b" ".join(toks)
        bad = b"\n".join(lines)
        with pytest.raises(ParseError) as err:
            parse_rows(bad, 0, 12, n_cols, "<fuzz>")
        assert err.value.line == k + 1, (kind, err.value)
        if kind in (0, 3):
            assert "expected a number" in str(err.value)
        else:
            assert f"expected {n_cols} values" in str(err.value)


def _sample_frames(n_frames):
    """The header and first ``n_frames`` frames of the shipped CMU take 86_09, as lines, and its skeleton."""
    data = read_bytes(SAMPLE_86_09)
    lines = data.split(b"\n")
    starts = [k for k, ln in enumerate(lines) if ln[:1].isdigit()]
    return lines[:starts[n_frames]], load_skeleton(SAMPLE_86_ASF)


def test_amc_bone_lines_read_as_float_reads_them():
    # every value of 40 real frames respelled (signs, leading zeros, exponents, long runs: the side-by-side
    # conversion and the exact scanner both), random blanks, tabs, CRLF, upper-case bone names, a comment
    rng = np.random.default_rng(9)
    lines, skeleton = _sample_frames(40)
    out = []
    for ln in lines:
        toks = ln.split()
        if not toks or toks[0][:1] in b":#" or toks[0][:1].isdigit():
            out.append(ln)
            continue
        vals = []
        for _ in toks[1:]:
            while True:
                t = _spelling(rng)
                f = _float_or_none(t)
                if f is not None and np.isfinite(f):
                    break
            vals.append(t)
        name = toks[0].upper() if rng.random() < 0.1 else toks[0]
        seps = [rng.choice([b" ", b"\t", b"  "]) for _ in vals]
        line = rng.choice([b"", b" "]) + name + b"".join(s + v for s, v in zip(seps, vals))
        out.append(line + rng.choice([b"", b" ", b"\r"]))
        if rng.random() < 0.02:
            out.append(b"# a comment")
    text = b"\n".join(out)
    m = parse_amc(text, skeleton)
    frames, _, _ = naive_amc_values(text, skeleton)
    assert m.n_frames == len(frames) == 40
    for name, sl in m.columns.items():
        assert _same_bits(m.values[:, sl], [fr[name] for fr in frames]), name


@pytest.mark.parametrize("later", ["unknown bone", "duplicate", "count", "frame number", "none"])
def test_amc_first_error_in_the_text_is_named(later):
    # a bad value, then another error later in the same frame (or the next frame's number): the bad value
    # is named, at its line; the values of a frame are converted when it ends, the error order stays the text's
    lines, skeleton = _sample_frames(3)
    frame2 = [k for k, ln in enumerate(lines) if ln[:1].isdigit()][1]
    bad = frame2 + 3
    toks = lines[bad].split()
    lines[bad] = b" ".join([toks[0], toks[1], b"1.5x", *toks[3:]])
    if later == "unknown bone":
        lines[frame2 + 6] = b"nosuchbone 1 2 3"
    elif later == "duplicate":
        lines[frame2 + 6] = lines[frame2 + 5]
    elif later == "count":
        lines[frame2 + 6] += b" 7"
    elif later == "frame number":
        lines[[k for k, ln in enumerate(lines) if ln[:1].isdigit()][2]] = b"9"
    with pytest.raises(ParseError) as err:
        parse_amc(b"\n".join(lines), skeleton)
    assert err.value.line == bad + 1, err.value
    assert "expected a number, found '1.5x'" in str(err.value)
    # and the other error alone is still named at its own line
    if later != "none":
        lines[bad] = b" ".join(toks)
        with pytest.raises(ParseError) as err:
            parse_amc(b"\n".join(lines), skeleton)
        assert err.value.line > bad + 1 and "1.5x" not in str(err.value)
