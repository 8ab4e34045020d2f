"""The helpers shared by the format readers (xtopo/io/formats/_common.py)."""

from __future__ import annotations

import numpy as np
import pytest

from xtopo.errors import ReaderError, UnitsError, UnsupportedFormatError
from xtopo.io.formats._common import (guarded, iso_time, parse_time, pick_channel, reading, sniff_magic,
                                      unix_time)
from xtopo.io.registry import ChannelInfo


def _info(i, name, is_height):
    return ChannelInfo(index=i, name=name, shape=(2, 2), size=(1.0, 1.0), units="m", height_units="m",
                       is_height=is_height)


INFOS = [_info(0, "Amplitude", False), _info(1, "Height", True), _info(2, "Phase", False)]


def test_pick_channel_on_names_and_infos_agrees():
    names = [c.name for c in INFOS]
    for channels in (names, INFOS):
        assert pick_channel("f.x", channels, 2) == 2
        assert pick_channel("f.x", channels, np.int64(1)) == 1
        assert pick_channel("f.x", channels, "Phase") == 2
        assert pick_channel("f.x", channels, " phase ") == 2  # case-insensitive, blanks stripped
    assert pick_channel("f.x", names, None) == 0  # names carry no height flag: the first
    assert pick_channel("f.x", INFOS, None) == 1  # the first height channel


def test_pick_channel_prefers_an_exact_name():
    assert pick_channel("f.x", ["z", "Z"], "Z") == 1
    assert pick_channel("f.x", ["z", "Z"], "z") == 0


@pytest.mark.parametrize("channels", [INFOS, [c.name for c in INFOS]])
@pytest.mark.parametrize("channel, words", [(3, "out of range"), (-1, "out of range"), ("Nope", "no channel named"),
                                            (1.5, "index or a name"), (True, "index or a name")])
def test_pick_channel_errors_name_the_file_and_list_the_channels(channels, channel, words):
    with pytest.raises(UnsupportedFormatError, match=words) as err:
        pick_channel("scan.x", channels, channel)
    msg = str(err.value)
    assert msg.startswith("scan.x: ") and "0: 'Amplitude', 1: 'Height', 2: 'Phase'" in msg


def test_pick_channel_of_no_channels():
    with pytest.raises(ReaderError, match="empty.x: the file holds no readable channel"):
        pick_channel("empty.x", [], None)


def test_reading_maps_every_failure_to_a_reader_error_naming_the_file():
    cases = [(KeyError("Rows"), "malformed Demo content \\(KeyError"),
             (UnitsError("unit 'furlong' unknown"), "invalid Demo header: unit 'furlong'"),
             (MemoryError(), "Demo reader gave up on malformed content: MemoryError")]
    for exc, words in cases:
        with pytest.raises(ReaderError, match=words) as err:
            with reading("bad.x", "Demo"):
                raise exc
        assert type(err.value) is ReaderError and err.value.path == "bad.x"
    original = UnsupportedFormatError("bad.x", "not this format")
    with pytest.raises(UnsupportedFormatError) as err:
        with reading("bad.x", "Demo"):
            raise original
    assert err.value is original  # reader errors pass unchanged


def test_guarded_is_reading_around_the_function():
    @guarded("Demo")
    def read(path, scale):
        return np.geterr(), np.array([1e308]) * float(scale)

    states, big = read("ok.x", 10.0)
    assert set(states.values()) == {"ignore"} and np.isinf(big[0])  # floating-point warnings are silenced
    with pytest.raises(ReaderError, match=r"^bad.x: malformed Demo content \(ValueError"):
        read("bad.x", "not a number")
    assert read.__name__ == "read"


def test_time_helpers():
    assert parse_time(" Tue  Mar 15 10:12:01 2011 ", "%Y", "%a %b %d %H:%M:%S %Y") == "2011-03-15T10:12:01"
    assert parse_time(None, "%Y") is None and parse_time("garbage", "%Y") is None
    assert iso_time(2020, 2, 29, 23, 59, 58) == "2020-02-29T23:59:58"
    assert iso_time(2021, 2, 29) is None and iso_time("x") is None
    assert unix_time(86400) == "1970-01-02T00:00:00+00:00"
    assert unix_time(0) is None and unix_time(0xFFFFFFFF) is None and unix_time("x") is None


def test_sniff_magic():
    sniff = sniff_magic(b"AB", b"CD")
    assert sniff(b"ABxx", "f") and sniff(b"CD", "f")
    assert not sniff(b"xAB", "f") and not sniff(b"", "f")
