"""`file_guard`, the one place the rules for reading untrusted files are written (issue 54):
devices, pipes and folders are refused by what they are, sizes are capped before and while
reading, archives are judged by their directory, JSON and XML nesting is bounded."""

from __future__ import annotations

import io
import os
import struct
import threading
import zipfile
import zlib

import pytest

from assistant.file_guard import (
    JSON_MAX_DEPTH,
    FileRefused,
    check_archive,
    json_depth,
    load_json,
    open_zip,
    read_file,
    xml_parser,
)

#: zlib.crc32 of 2**31 zero bytes (computed once; the bomb below is 2 GiB of zeros).
CRC_2GIB_ZEROS = 0x4DBDF21C


def zip_bomb(name: str = "3D/3dmodel.model", blocks: int = 128) -> bytes:
    """A real zip of about 2 MB whose member inflates to `blocks` x 16 MiB of zeros (2 GiB):
    the raw deflate stream of one 16 MiB block, fully flushed, repeats exactly, so it is
    written in milliseconds instead of compressing 2 GiB."""
    block = bytes(16 * 2**20)
    c = zlib.compressobj(9, zlib.DEFLATED, -15)
    seg = c.compress(block) + c.flush(zlib.Z_FULL_FLUSH)
    data = seg * blocks + c.flush(zlib.Z_FINISH)
    size = blocks * len(block)
    crc = CRC_2GIB_ZEROS if blocks == 128 else _crc_of_zeros(size)
    raw = name.encode()
    local = struct.pack("<IHHHHHIIIHH", 0x04034B50, 20, 0, 8, 0, 0x21, crc, len(data), size,
                        len(raw), 0) + raw
    central = struct.pack("<IHHHHHHIIIHHHHHII", 0x02014B50, 20, 20, 0, 8, 0, 0x21, crc,
                          len(data), size, len(raw), 0, 0, 0, 0, 0, 0) + raw
    end = struct.pack("<IHHHHIIH", 0x06054B50, 0, 0, 1, 1, len(central),
                      len(local) + len(data), 0)
    return local + data + central + end


def _crc_of_zeros(n: int) -> int:
    crc, block = 0, bytes(2**20)
    for _ in range(n // len(block)):
        crc = zlib.crc32(block, crc)
    return crc


def test_a_small_bomb_is_a_valid_zip_that_inflates_as_declared():
    data = zip_bomb(blocks=2)  # 32 MiB: small enough to inflate here
    with zipfile.ZipFile(io.BytesIO(data)) as zf:
        assert zf.read("3D/3dmodel.model") == bytes(32 * 2**20)  # CRC checked by zipfile


def test_a_2_mb_archive_declaring_2_gib_is_refused_from_its_directory():
    data = zip_bomb()
    assert len(data) < 2.2e6
    with pytest.raises(FileRefused, match=r"would expand from 2 MiB to 2,048 MiB.*zip bomb"):
        open_zip(data, what="3MF archive", max_total=2**30)
    # within the ratio but over the total: refused too, by the total
    infos = [zipfile.ZipInfo(f"m{i}") for i in range(3)]
    for info in infos:
        info.file_size, info.compress_size = 400 * 2**20, 100 * 2**20
    with pytest.raises(FileRefused, match="would expand to more than 1,024 MiB"):
        check_archive(infos, what="cell zip", max_total=2**30)
    assert check_archive(infos[:2], what="cell zip", max_total=2**30) == infos[:2]


def test_devices_pipes_and_folders_are_refused_by_what_they_are(tmp_path):
    with pytest.raises(FileRefused, match=r"/dev/zero is a character device, not a CAD file"):
        read_file("/dev/zero", limit=2**20, what="CAD file")
    with pytest.raises(FileRefused, match="is a folder"):
        read_file(tmp_path, limit=2**20)
    fifo = tmp_path / "pipe.stl"
    os.mkfifo(fifo)
    # No writer ever opens the pipe: a blocking open would hang here for good.
    done: list = []
    t = threading.Thread(target=lambda: done.append(_refusal(fifo)), daemon=True)
    t.start()
    t.join(timeout=30)
    assert done and "named pipe (FIFO)" in done[0]


def _refusal(path) -> str:
    try:
        read_file(path, limit=2**20)
    except FileRefused as exc:
        return str(exc)
    return "read"


def test_sizes_are_capped_before_and_while_reading(tmp_path):
    big = tmp_path / "big.stl"
    big.write_bytes(bytes(2048))
    with pytest.raises(FileRefused, match="is 2,048 bytes, more than the 1,024 bytes"):
        read_file(big, limit=1024)
    assert read_file(big, limit=2048) == bytes(2048)
    # /proc files say 0 bytes and yield more: the read stops at the cap
    with pytest.raises(FileRefused, match="yields more than"):
        read_file("/proc/self/maps", limit=16)
    with pytest.raises(FileRefused, match="cannot be opened"):
        read_file(tmp_path / "missing.stl", limit=16)


def test_json_depth_is_measured_before_parsing():
    assert json_depth(b'{"a": [1, {"b": "[[[[{{{"}], "c": "\\"[["}') == 3
    assert json_depth(b"[]") == 1 and json_depth(b"7") == 0
    deep = b"[" * 200_000 + b"]" * 200_000  # would overflow the recursive parser
    with pytest.raises(FileRefused, match=f"nests 200000 levels deep, more than the "
                                          f"{JSON_MAX_DEPTH}"):
        load_json(deep, what="glTF JSON", limit=2**20)
    with pytest.raises(FileRefused, match="not valid JSON"):
        load_json(b'{"a": NaN}', what="cell.json", limit=2**20)
    assert load_json(b'{"a": [1, 2]}', what="x", limit=100) == {"a": [1, 2]}


def test_xml_is_parsed_without_entities_and_depth_is_bounded():
    from lxml import etree

    with pytest.raises(etree.XMLSyntaxError, match="Excessive depth"):
        etree.fromstring(b"<a>" * 1000 + b"</a>" * 1000, xml_parser())
    external = (b'<?xml version="1.0"?><!DOCTYPE r [<!ENTITY x SYSTEM "file:///dev/zero">]>'
                b"<robot name='&x;'/>")
    with pytest.raises(etree.XMLSyntaxError):
        etree.fromstring(external, xml_parser())
    assert etree.fromstring(b"<a><b/></a>", xml_parser()).tag == "a"
