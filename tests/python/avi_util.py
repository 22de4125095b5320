"""Test helper: a Motion-JPEG AVI written with the standard library (RIFF chunks, one JPEG per
frame), as drones and cameras record them, for the video import's tests without cv2 or ffmpeg in
Python. The AVI layout is Microsoft's (avih, strh, strf as BITMAPINFOHEADER, movi, idx1)."""
from __future__ import annotations

import struct
from pathlib import Path


def _chunk(fourcc: bytes, data: bytes) -> bytes:
    return fourcc + struct.pack("<I", len(data)) + data + (b"\0" if len(data) % 2 else b"")


def _list(kind: bytes, data: bytes) -> bytes:
    return _chunk(b"LIST", kind + data)


def write_mjpeg_avi(path: Path, jpegs: list[bytes], width: int, height: int, fps: int) -> None:
    """Writes `jpegs` (baseline JPEG files' bytes, width x height each) as an AVI at `fps`."""
    n = len(jpegs)
    largest = max(len(j) for j in jpegs)
    avih = struct.pack("<10I4I", 1_000_000 // fps, largest * fps, 0, 0x10, n, 0, 1, largest,
                       width, height, 0, 0, 0, 0)
    strh = (b"vids" + b"MJPG" + struct.pack("<IHHIIIIIIiI", 0, 0, 0, 0, 1, fps, 0, n, largest, -1, 0)
            + struct.pack("<4h", 0, 0, width, height))
    strf = struct.pack("<IiiHH4sIiiII", 40, width, height, 1, 24, b"MJPG", width * height * 3,
                       0, 0, 0, 0)
    header = _list(b"hdrl", _chunk(b"avih", avih) + _list(b"strl", _chunk(b"strh", strh)
                                                          + _chunk(b"strf", strf)))
    movi = b""
    index = b""
    for jpeg in jpegs:
        index += b"00dc" + struct.pack("<III", 0x10, 4 + len(movi), len(jpeg))
        movi += _chunk(b"00dc", jpeg)
    body = b"AVI " + header + _list(b"movi", movi) + _chunk(b"idx1", index)
    path.write_bytes(b"RIFF" + struct.pack("<I", len(body)) + body)
