#!/usr/bin/env python3
"""Seeded mutation fuzzer over every file reader of aos, through `aos-render` and `import aos`,
and over the requests of the viewer's HTTP and WebSocket server.

What it does
------------
1. Builds a seed corpus in a temporary folder with the aos build under test (deterministic, the
   same for every seed): a tiny simulated light field (`aos-render simulate`, 3 x 3 views of
   32 x 32 pixels) with its `lightfield.json`, the same views as a JKU-style `poses.json`, the
   scene file, an aos-camera file, a focal stack folder (`aos-render stack`: stack.json and
   TIFFs), COLMAP text and binary models of the views, a positions CSV (name,x,y,z), one
   image of every format (PNG 8/16-bit, TIFF uint8/uint16/float32, EXR, JPEG) with a copy of each
   as a metrics reference, two telemetry logs of the views (by frame name, by time), three JPEG
   frames with EXIF GPS and DJI XMP gimbal tags, a terrain under the views as OBJ, ascii PLY,
   binary PLY and DEM (float32 GeoTIFF), a mask for every view and a folder of masks one per
   view, the plan's polygon (--vertices) and a DEM under it (UTM zone 33), and the viewer's
   requests (viewer/*.json: HTTP bodies or query strings, and WebSocket messages).
2. Runs the unmutated corpus through every target once; each must come out `ok` (this checks
   that the time and memory limits fit the build).
3. Runs N cases. Case i draws from `random.Random(f"{seed}:{i}")` (so any case can be replayed
   alone, and --jobs does not change the cases): a target (round robin over the targets), one of
   the corpus files that target reads, and a mutation of it: byte-level (bit flips, interesting
   bytes and integers, insertion, deletion, truncation, chunk duplication, splicing with another
   corpus file), structural for the file's type (JSON values of another type, 1e999, negative,
   zero and huge sizes, unknown and misspelled keys, deep nesting, invalid UTF-8, empty strings;
   CSV, OBJ and COLMAP text tokens; PNG/TIFF/JPEG/EXR size fields set huge with valid
   checksums, truncated image data, non-finite float samples; GeoTIFF pixel scale and tie
   point; COLMAP binary counts; PLY element counts, property types and formats; EXIF GPS
   rationals, reference letters and entries, DJI XMP values and a packet cut short; plan
   vertices non-finite, huge, repeated, self-intersecting; viewer requests past the server's
   64 KiB limit, or with another Host or Origin header), or a special file in its place (a
   FIFO, a link to /dev/zero, a folder) or the output path set to that input file. These
   hand-made cases fill rounds 1 to 4 over the targets (cases n to 5n - 1 for n targets: every
   target that reads its file itself gets each once) and 2 % of the later cases.
4. Runs the target on a private copy of the corpus, in its own folder, under a timeout
   (SIGTERM, then SIGKILL if it still runs --term-grace seconds later), an address-space limit
   (RLIMIT_AS) and a peak-RSS budget, and classifies the run. CLI targets are one `aos-render`
   process per case ({text} in a target's command: the mutated file's bytes as one argument);
   Python targets run in a worker process (`fuzz.py --worker`, restarted after a crash or a
   hang) that imports aos once. Viewer targets send one request per case (HTTP with the token
   header, or a WebSocket text message followed by a sentinel message that the server answers at
   once) to an `aos-render view` server on 127.0.0.1 (a free port, its own token read from its
   --json line) that each job thread starts once and again after it died or hung.
5. Saves every failing case under --out: the minimised input file (delta debugging, bounded in
   time), `case.json` (target, seed, case index, class, mutation, command, stderr tail) and
   `reproduce.sh` (rebuilds the case folder from the saved corpus and runs the command).

Classes
-------
ok                accepted (exit 0 / no exception) and the output passed the checks below
refused           exit != 0 with exactly one stderr line containing "error", the last one, naming
                  the mutated file (its base name); in Python a ValueError naming it, one line
signal            killed by a signal other than our timeout's SIGKILL (crash, abort), or the
                  Python worker exited in the middle of a call
timeout           still running after --timeout seconds, ended by SIGTERM (viewer: no answer
                  in time, or the connection dropped while the server lives)
ignores-sigterm   still running --term-grace seconds after the timeout's SIGTERM (killed)
memory            std::bad_alloc / MemoryError / "Cannot allocate memory", SIGKILL not sent by
                  us (the kernel's OOM killer), or a peak RSS above --rss-limit-mb
traceback         "Traceback (most recent call last)" on the CLI's stderr, or a Python exception
                  of another type than ValueError, or (viewer) a traceback or "Error handling
                  request" in the server's log during the request
server-error      viewer: an HTTP 5xx (or 3xx) answer, a WebSocket closed with a code other
                  than 1003/1007/1009, or an error message reporting an exception the server
                  did not handle ("RuntimeError: ..."). A 4xx answer, an error message or a
                  1003/1007/1009 close is `refused`; the server dying is `signal`
multi-line-error  more than one stderr line containing "error", or lines after the error line,
                  or a ValueError message of several lines
unnamed-error     the error line / ValueError message does not contain the mutated file's name
                  (also: exit != 0 without any error line)
partial-output    exit != 0 and something was left in the output folder, or a new file or
                  folder (hidden temporary files included) appeared beside the inputs
modified-input    an input file's bytes or mtime changed or it disappeared, or (on success) a new
                  file appeared among the inputs
accepted-invalid  exit 0 (no exception), but the mutated input is an image the fuzzer can
                  prove incomplete or invalid (`image_defect`; not for targets that read only
                  image headers and tags, decodes_pixels=False), a frame of the EXIF target
                  whose GPS tags cannot be a position (`gps_defect`: a reference letter other
                  than N/S, E/W, a zero denominator, 60 minutes or seconds, more than 90/180
                  degrees), or an output is invalid.
                  Inputs: a PNG without IHDR or IDAT, with an invalid IHDR (zero size, bad
                  depth or colour type), a wrong CRC on a critical chunk, a zlib stream that
                  ends or fails before yielding the bytes the IHDR size needs (an error after
                  them, e.g. in the checksum, is not counted), or a row filter byte > 4; a TIFF
                  declaring more than 10000 x its file size in samples, with fewer strips than
                  its rows need, a strip whose bytes present (deflate: once inflated) are fewer
                  than its rows need, a strip of another compression running past the end of
                  the file, or an uncompressed float sample that is NaN or infinite; a JPEG
                  without the end-of-image marker after its scan, or declaring more than 1000
                  samples per file byte; a scanline EXR whose chunk table or a chunk runs past
                  the end of the file, or declaring more than 1000 samples per file byte.
                  Outputs: a promised output missing, a float TIFF holding NaN, a JSON or GeoJSON
                  file that does not parse or holds NaN/Infinity, a KML file that is not XML, a
                  CSV file with a row of another length or a field that is not a finite number,
                  an image with one of the defects above, the metrics JSON on stdout not finite,
                  a Python result holding a float array with NaN or infinity; viewer: a frame
                  whose RGBA bytes do not match its header's size, a JSON answer not finite.

The first class that applies wins, in this order: ignores-sigterm, timeout, signal, memory,
modified-input, partial-output, traceback, multi-line-error, unnamed-error, accepted-invalid,
then refused/ok (viewer: signal, traceback, memory, timeout, server-error, accepted-invalid,
refused/ok). A refusal names the mutated file's base name, or for a {text} target the
target's error_name (the option it fills).

Usage
-----
    python3 tools/fuzz.py --seed 1 --cases 300 --time-limit 60
    python3 tools/fuzz.py --seed 1 --cases 1500 --time-limit 600 --jobs 2 \\
        --aos-render /path/to/aos-render --python-path /path/to/site --out fuzz-out
    python3 tools/fuzz.py --seed 1 --case 137          # replay one case
    python3 tools/fuzz.py --list-targets

Prints a table (cases per target and class, time) and the distinct failures; --json prints one
JSON object instead. Exit status 1 if any failure class occurred, 0 if none, 2 if the set-up
failed (no aos, or the unmutated corpus does not pass). Standard library and numpy only.
"""
from __future__ import annotations

import argparse
import base64
import concurrent.futures
import dataclasses
import hashlib
import http.client
import json
import math
import os
import random
import re
import resource
import select
import shlex
import shutil
import signal
import socket
import stat
import struct
import subprocess
import sys
import tempfile
import threading
import time
import urllib.parse
import zlib
from pathlib import Path
from typing import Callable, Iterable, Optional

FAILURE_CLASSES = ("signal", "timeout", "ignores-sigterm", "memory", "server-error", "traceback",
                   "multi-line-error", "unnamed-error", "partial-output", "modified-input",
                   "accepted-invalid")
CLASSES = ("ok", "refused") + FAILURE_CLASSES

# Environment of every child: a bounded number of threads and malloc arenas keeps the address
# space (RLIMIT_AS) of a run independent of the machine's core count.
CHILD_ENV = {"OMP_NUM_THREADS": "2", "MALLOC_ARENA_MAX": "2", "OPENBLAS_NUM_THREADS": "1",
             "LC_ALL": "C.UTF-8"}

# The virtual camera of every render: 20 m above the origin looking down, 32 x 32 pixels.
VIRTUAL_CAMERA = ["--look-at", "0,0,20,0,0,0,0,1,0", "--fov-deg", "50", "--width", "32",
                  "--height", "32"]
FRAMES_FOV_DEG = 50.0   # the simulated views' horizontal field of view (scene camera below)
IMAGE_SIZE = 32         # width and height of every corpus image, pixels

TINY_SCENE = {
    "seed": 7,
    "occluders": {"voxels": {"center": [0, 0, 8], "size": [10, 10, 4], "grid": [10, 10, 4],
                             "density": 0.3}},
    "camera": {"width": IMAGE_SIZE, "height": IMAGE_SIZE, "fov_deg": FRAMES_FOV_DEG},
    "sampling": {"altitude": 20, "grid": 3, "aperture": {"diameter": 4}},
    "truth": {"width": 8, "height": 8, "blocked_fraction": False},
}


# =============================================================================================
# Image formats: hand-written headers, a float TIFF decoder, and the defects the fuzzer can prove.

def png_chunk(kind: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))


def png_chunks(data: bytes) -> list[tuple[int, bytes, bytes, int]]:
    """(offset, type, payload, stored CRC) of each complete chunk after the signature."""
    chunks, pos = [], 8
    while pos + 12 <= len(data):
        length, kind = struct.unpack(">I4s", data[pos:pos + 8])
        if pos + 12 + length > len(data):
            break
        payload = data[pos + 8:pos + 8 + length]
        (crc,) = struct.unpack(">I", data[pos + 8 + length:pos + 12 + length])
        chunks.append((pos, kind, payload, crc))
        pos += 12 + length
    return chunks


def tiff_file(width: int, height: int, pixels: bytes, bits: int, sample_format: int) -> bytes:
    """An uncompressed single-strip, single-channel little-endian TIFF."""
    entries = [(256, 4, width), (257, 4, height), (258, 3, bits), (259, 3, 1), (262, 3, 1),
               (273, 4, 0), (277, 3, 1), (278, 4, height), (279, 4, len(pixels)),
               (284, 3, 1), (339, 3, sample_format)]
    ifd_size = 2 + 12 * len(entries) + 4
    data_offset = 8 + ifd_size
    ifd = struct.pack("<H", len(entries))
    for tag, kind, value in entries:
        value = data_offset if tag == 273 else value
        ifd += struct.pack("<HHI", tag, kind, 1)
        ifd += struct.pack("<HH", value, 0) if kind == 3 else struct.pack("<I", value)
    return b"II*\0" + struct.pack("<I", 8) + ifd + struct.pack("<I", 0) + pixels


class Tiff:
    """The first IFD of a classic TIFF: the fields the readers and the checks need."""
    TYPE_SIZES = {1: 1, 2: 1, 3: 2, 4: 4, 5: 8, 6: 1, 7: 1, 8: 2, 9: 4, 10: 8, 11: 4, 12: 8, 16: 8}

    def __init__(self, data: bytes):
        if data[:4] not in (b"II*\0", b"MM\0*"):
            raise ValueError("not a classic TIFF")
        self.order = "<" if data[:2] == b"II" else ">"
        self.tags: dict[int, list[int]] = {}
        self.tag_positions: dict[int, tuple[int, int]] = {}   # tag -> (value offset, type)
        (ifd,) = struct.unpack(self.order + "I", data[4:8])
        (count,) = struct.unpack(self.order + "H", data[ifd:ifd + 2])
        for i in range(count):
            entry = ifd + 2 + 12 * i
            tag, kind, n = struct.unpack(self.order + "HHI", data[entry:entry + 8])
            size = self.TYPE_SIZES.get(kind, 1) * n
            (pointer,) = struct.unpack(self.order + "I", data[entry + 8:entry + 12])
            where = entry + 8 if size <= 4 else pointer
            self.tag_positions[tag] = (where, kind)
            if kind in (3, 4) and n <= 1 << 16 and where + size <= len(data):
                code = "H" if kind == 3 else "I"
                values = struct.unpack(f"{self.order}{n}{code}", data[where:where + size])
                self.tags[tag] = list(values)
        self.width = self.first(256)
        self.height = self.first(257)
        self.bits = self.first(258, 1)
        self.spp = self.first(277, 1)
        self.compression = self.first(259, 1)
        self.predictor = self.first(317, 1)
        self.sample_format = self.first(339, 1)
        self.tiled = 324 in self.tags or 322 in self.tags
        self.offsets = self.tags.get(324 if self.tiled else 273, [])
        self.counts = self.tags.get(325 if self.tiled else 279, [])
        self.rows_per_strip = self.first(278, self.height)

    def first(self, tag: int, default: Optional[int] = None) -> int:
        values = self.tags.get(tag)
        if values:
            return values[0]
        if default is None:
            raise ValueError(f"TIFF tag {tag} missing")
        return default

    def decode_float(self, data: bytes):
        """The float32 samples (numpy, flat) of a stripped TIFF without compression or with
        deflate and predictor 1 or 3; None for any other layout."""
        import numpy as np
        if (self.tiled or self.bits != 32 or self.sample_format != 3 or self.first(284, 1) != 1
                or self.compression not in (1, 8, 32946) or self.predictor not in (1, 3)):
            return None
        row_values = self.width * self.spp
        rows = []
        for offset, count in zip(self.offsets, self.counts):
            strip = data[offset:offset + count]
            if self.compression != 1:
                strip = zlib.decompress(strip)
            strip_rows = len(strip) // (4 * row_values)
            for r in range(strip_rows):
                row = strip[r * 4 * row_values:(r + 1) * 4 * row_values]
                if self.predictor == 3:   # libtiff's floating-point predictor: bytes planar, diffed
                    raw = np.frombuffer(row, np.uint8).reshape(-1, self.spp)
                    raw = np.cumsum(raw, axis=0, dtype=np.uint8).reshape(4, row_values)
                    rows.append(raw.T.copy().view(">f4").ravel())
                else:
                    rows.append(np.frombuffer(row, self.order + "f4"))
        return np.concatenate(rows) if rows else np.zeros(0, np.float32)


PNG_CHANNELS = {0: 1, 2: 3, 3: 1, 4: 2, 6: 4}
PNG_DEPTHS = {0: (1, 2, 4, 8, 16), 2: (8, 16), 3: (1, 2, 4, 8), 4: (8, 16), 6: (8, 16)}
INFLATE_CAP = 1 << 28   # bytes of PNG image data decompressed at most by the check


def inflate_prefix(stream: bytes, limit: int) -> tuple[bytes, str]:
    """The first `limit` bytes (or fewer) a zlib stream inflates to, and the zlib error that
    stopped it early ("" if none). An error after `limit` bytes (e.g. a wrong checksum in the
    trailer) is not reported: the pixels are all there."""
    inflater, output, step = zlib.decompressobj(), bytearray(), 256
    for start in range(0, len(stream), step):
        try:
            output += inflater.decompress(stream[start:start + step], limit + 1 - len(output))
        except zlib.error as error:
            return bytes(output), str(error)
        if len(output) > limit or inflater.eof:
            break
    return bytes(output[:limit + 1]), ""


def png_defect(data: bytes) -> Optional[str]:
    chunks = png_chunks(data)
    if not chunks or chunks[0][1] != b"IHDR" or len(chunks[0][2]) != 13:
        return "no IHDR chunk"
    for _, kind, payload, crc in chunks:
        if kind in (b"IHDR", b"PLTE", b"IDAT", b"IEND") and zlib.crc32(kind + payload) != crc:
            return f"{kind.decode()} chunk CRC mismatch"
    width, height, depth, color, _, _, interlace = struct.unpack(">IIBBBBB", chunks[0][2])
    if width == 0 or height == 0 or color not in PNG_DEPTHS or depth not in PNG_DEPTHS[color] \
            or interlace > 1:
        return f"invalid IHDR ({width}x{height}, depth {depth}, colour type {color})"
    bits = PNG_CHANNELS[color] * depth
    if interlace:   # Adam7: seven sub-images
        passes = [((width - x0 + dx - 1) // dx, (height - y0 + dy - 1) // dy) for x0, y0, dx, dy in
                  ((0, 0, 8, 8), (4, 0, 8, 8), (0, 4, 4, 8), (2, 0, 4, 4), (0, 2, 2, 4),
                   (1, 0, 2, 2), (0, 1, 1, 2))]
        needed = sum(h * (1 + (w * bits + 7) // 8) for w, h in passes if w and h)
    else:
        needed = height * (1 + (width * bits + 7) // 8)
    stream = b"".join(payload for _, kind, payload, _ in chunks if kind == b"IDAT")
    if not stream:
        return "no IDAT chunk"
    pixels, error = inflate_prefix(stream, min(needed, INFLATE_CAP))
    if len(pixels) < needed and len(pixels) < INFLATE_CAP:
        return f"image data inflates to {len(pixels)} of the {needed} bytes the IHDR size needs" \
            + (f" ({error})" if error else "")
    if not interlace:
        stride = 1 + (width * bits + 7) // 8
        if any(f > 4 for f in pixels[0:min(len(pixels), needed):stride]):
            return "invalid row filter byte"
    return None


def tiff_defect(data: bytes) -> Optional[str]:
    try:
        tiff = Tiff(data)
    except (ValueError, struct.error):
        return None   # a layout this check does not read: nothing proven
    needed = tiff.width * tiff.height * tiff.spp * tiff.bits // 8
    if needed > 10000 * len(data):
        return (f"declares {tiff.width}x{tiff.height}x{tiff.spp} samples of {tiff.bits} bits "
                f"in {len(data)} bytes")
    row_bytes = (tiff.width * tiff.spp * tiff.bits + 7) // 8
    if tiff.tiled or tiff.rows_per_strip <= 0 or len(tiff.offsets) != len(tiff.counts):
        return None
    strips = -(-tiff.height // tiff.rows_per_strip)
    if len(tiff.offsets) < strips:
        return (f"{tiff.height} rows need {strips} strips of {tiff.rows_per_strip} rows, "
                f"the file has {len(tiff.offsets)}")
    for i, (offset, count) in enumerate(zip(tiff.offsets, tiff.counts)):
        rows = max(min(tiff.rows_per_strip, tiff.height - i * tiff.rows_per_strip), 0)
        strip_needed = rows * row_bytes
        present = data[offset:offset + count]
        if tiff.compression in (8, 32946):   # deflate: what the bytes present inflate to
            present, _ = inflate_prefix(present, strip_needed)
        elif tiff.compression != 1:
            if offset + count > len(data):
                return f"strip {i} ({count} bytes at {offset}) runs past the end of the file"
            continue
        if len(present) < strip_needed:
            return f"strip {i} holds {len(present)} of the {strip_needed} bytes its rows need"
    if tiff.compression == 1:
        samples = tiff.decode_float(data)
        if samples is not None:
            import numpy as np
            bad = int(np.count_nonzero(~np.isfinite(samples)))
            if bad:
                return f"{bad} non-finite float samples"
    return None


def jpeg_defect(data: bytes) -> Optional[str]:
    pos, size = 2, None
    while pos + 4 <= len(data):
        if data[pos] != 0xFF:
            return None   # not a marker where one must be: a layout this check does not follow
        marker = data[pos + 1]
        if marker == 0xFF:
            pos += 1
            continue
        (length,) = struct.unpack(">H", data[pos + 2:pos + 4])
        if 0xC0 <= marker <= 0xCF and marker not in (0xC4, 0xC8, 0xCC) and pos + 10 <= len(data):
            height, width, components = struct.unpack(">HHB", data[pos + 5:pos + 10])
            size = (width, height, components)
        if marker == 0xDA:   # start of scan: the end-of-image marker must follow the data
            if data.find(b"\xff\xd9", pos + 2 + length) < 0:
                return "no end-of-image marker after the scan (truncated)"
            break
        pos += 2 + length
    if size and size[0] * size[1] * size[2] > 1000 * len(data):
        return f"declares {size[0]}x{size[1]}x{size[2]} samples in {len(data)} bytes"
    return None


EXR_LINES_PER_CHUNK = {0: 1, 1: 1, 2: 1, 3: 16, 4: 32, 5: 16, 6: 32, 7: 32, 8: 32, 9: 256}


def exr_header(data: bytes) -> tuple[dict[str, tuple[str, int, bytes]], int]:
    """Attributes (name -> (type, offset of the value, value)) and the offset after the header."""
    attributes, pos = {}, 8
    while True:
        name_end = data.index(b"\0", pos)
        if name_end == pos:
            return attributes, pos + 1
        type_end = data.index(b"\0", name_end + 1)
        (size,) = struct.unpack("<i", data[type_end + 1:type_end + 5])
        value_at = type_end + 5
        attributes[data[pos:name_end].decode("latin-1")] = (
            data[name_end + 1:type_end].decode("latin-1"), value_at, data[value_at:value_at + size])
        pos = value_at + size


def exr_channel_count(chlist: bytes) -> int:
    """Entries of a chlist: name, NUL, then 16 bytes (type, pLinear, reserved, x/y sampling)."""
    count, pos = 0, 0
    while pos < len(chlist) and chlist[pos] != 0:
        pos = chlist.index(b"\0", pos) + 1 + 16
        count += 1
    return count


def exr_defect(data: bytes) -> Optional[str]:
    if data[:4] != b"v/1\x01" or data[5] & 0x02:   # tiled files: not followed
        return None
    try:
        attributes, pos = exr_header(data)
        x0, y0, x1, y1 = struct.unpack("<4i", attributes["dataWindow"][2][:16])
        compression = attributes["compression"][2][0]
        channels = exr_channel_count(attributes["channels"][2])
    except (ValueError, KeyError, IndexError, struct.error):
        return None
    width, height = x1 - x0 + 1, y1 - y0 + 1
    if width <= 0 or height <= 0 or compression not in EXR_LINES_PER_CHUNK:
        return None
    if width * height * max(channels, 1) > 1000 * len(data):
        return f"declares {width}x{height}x{channels} samples in {len(data)} bytes"
    chunks = -(-height // EXR_LINES_PER_CHUNK[compression])
    if pos + 8 * chunks > len(data):
        return "the chunk offset table runs past the end of the file"
    for (offset,) in struct.iter_unpack("<Q", data[pos:pos + 8 * chunks]):
        if offset + 8 > len(data):
            return f"a chunk offset ({offset}) lies past the end of the file ({len(data)} bytes)"
        (size,) = struct.unpack("<i", data[offset + 4:offset + 8])
        if offset + 8 + size > len(data):
            return f"the chunk at {offset} ({size} bytes) runs past the end of the file"
    return None


def image_defect(path: Path) -> Optional[str]:
    """Why the image file at `path` cannot be a complete, valid image, when the fuzzer can prove
    it (see the module docstring); None when it found nothing (which proves nothing)."""
    try:
        if not path.is_file() or path.is_symlink():
            return None
        data = path.read_bytes()
    except OSError:
        return None
    checks = {b"\x89PNG\r\n\x1a\n": png_defect, b"II*\0": tiff_defect, b"MM\0*": tiff_defect,
              b"\xff\xd8": jpeg_defect, b"v/1\x01": exr_defect}
    for magic, check in checks.items():
        if data.startswith(magic):
            try:
                return check(data)
            except Exception:   # a header these parsers cannot follow: nothing proven
                return None
    return None


def gps_defect(data: bytes) -> Optional[str]:
    """Why the EXIF GPS tags of a frame cannot be a position, when the fuzzer can prove it: a
    GPSLatitudeRef other than N or S, a GPSLongitudeRef other than E or W, a degrees, minutes,
    seconds rational with a zero denominator, minutes or seconds of 60 or more, or more than 90
    (180) degrees. Tags whose type was changed are not judged (a reader may skip them)."""
    try:
        base, entries = exif_entries(data)
    except (ValueError, struct.error):
        return None
    names = {1: "GPSLatitudeRef", 2: "GPSLatitude", 3: "GPSLongitudeRef", 4: "GPSLongitude"}
    for entry, tag, kind, count, _ in entries:
        if tag in (1, 3) and kind == 2 and 1 <= count <= 4:
            letter = data[entry + 8:entry + 9]
            if letter not in ((b"N", b"S") if tag == 1 else (b"E", b"W")):
                return f"{names[tag]} is {data[entry + 8:entry + 8 + count]!r}"
        if tag in (2, 4) and kind == 5 and count == 3:
            (offset,) = struct.unpack("<I", data[entry + 8:entry + 12])
            at = base + offset
            if at + 24 > len(data):
                continue
            values = struct.unpack("<6I", data[at:at + 24])
            if 0 in values[1::2]:
                return f"{names[tag]} has a zero denominator: {values}"
            degrees, minutes, seconds = (values[i] / values[i + 1] for i in (0, 2, 4))
            if minutes >= 60 or seconds >= 60 or degrees > (90 if tag == 2 else 180):
                return f"{names[tag]} is {degrees:g} deg {minutes:g}' {seconds:g}\""
    return None


def float_tiff_nan(path: Path) -> Optional[str]:
    """'N NaN samples' for a float TIFF output holding NaN (outputs may hold infinities, e.g.
    depths of the sky, but NaN never)."""
    try:
        data = path.read_bytes()
        samples = Tiff(data).decode_float(data)
    except Exception:   # not a float TIFF this decoder reads: nothing proven
        return None
    if samples is None:
        return None
    import numpy as np
    nan = int(np.count_nonzero(np.isnan(samples)))
    return f"{nan} NaN samples" if nan else None


def strict_json(text: str | bytes) -> object:
    """json.loads refusing NaN and infinities."""
    def refuse(token: str) -> None:
        raise ValueError(f"non-finite number {token}")
    return json.loads(text, parse_constant=refuse)


def csv_defect(text: str) -> Optional[str]:
    """A CSV output (the plan's waypoints): every row has the header's number of fields, and
    every field after the header is a finite number."""
    lines = [line for line in text.splitlines() if line.strip()]
    if not lines:
        return "an empty CSV file"
    width = len(lines[0].split(","))
    for number, line in enumerate(lines[1:], start=2):
        fields = line.split(",")
        if len(fields) != width:
            return f"line {number} has {len(fields)} fields, the header {width}"
        for field in fields:
            try:
                value = float(field)
            except ValueError:
                return f"line {number}: {field[:40]!r} is not a number"
            if not math.isfinite(value):
                return f"line {number}: {field} is not finite"
    return None


def output_defect(path: Path) -> Optional[str]:
    suffix = path.suffix.lower()
    if suffix in (".csv", ".geojson", ".kml"):
        try:
            text = path.read_bytes().decode("utf-8")
            if suffix == ".csv":
                return csv_defect(text)
            if suffix == ".geojson":
                strict_json(text)
            else:
                import xml.etree.ElementTree as ElementTree
                ElementTree.fromstring(text)
        except (ValueError, UnicodeDecodeError) as error:
            return f"invalid {suffix[1:].upper()} ({error})"
        except SyntaxError as error:   # xml.etree.ElementTree.ParseError
            return f"invalid {suffix[1:].upper()} ({type(error).__name__}: {error})"
        return None
    if suffix in (".tif", ".tiff"):
        nan = float_tiff_nan(path)
        if nan:
            return nan
    if suffix == ".json":
        try:
            strict_json(path.read_bytes())
        except (ValueError, UnicodeDecodeError) as error:
            return f"invalid JSON ({error})"
    return image_defect(path)


# =============================================================================================
# Mutations. Each takes (rng, data, context) and returns (new data, description).

INTERESTING_BYTES = (0x00, 0x01, 0x7F, 0x80, 0xFF, 0x20, 0x0A, 0x22, 0x2D)
INTERESTING_INTS = (0, 1, -1, 2, 0x7F, 0x80, 0xFF, 0x7FFF, 0x8000, 0xFFFF, 0x7FFFFFFF,
                    0x80000000, 0xFFFFFFFF, 46340, 30000, 65536, 1 << 20)


@dataclasses.dataclass
class MutationContext:
    name: str                           # corpus-relative path of the file being mutated
    others: list[tuple[str, bytes]]     # every corpus file, for splicing


def flip_bits(rng, data, ctx):
    data = bytearray(data)
    n = rng.choice((1, 1, 2, 4, 8))
    for _ in range(n):
        i = rng.randrange(len(data))
        data[i] ^= 1 << rng.randrange(8)
    return bytes(data), f"flip {n} bits"


def set_bytes(rng, data, ctx):
    data = bytearray(data)
    n = rng.choice((1, 2, 4))
    where = []
    for _ in range(n):
        i = rng.randrange(len(data))
        data[i] = rng.choice(INTERESTING_BYTES)
        where.append(i)
    return bytes(data), f"set bytes at {where}"


def set_integer(rng, data, ctx):
    size, order = rng.choice((2, 4, 8)), rng.choice("<>")
    if len(data) < size:
        return flip_bits(rng, data, ctx)
    i = rng.randrange(len(data) - size + 1)
    value = rng.choice(INTERESTING_INTS) & ((1 << (8 * size)) - 1)
    code = {2: "H", 4: "I", 8: "Q"}[size]
    return data[:i] + struct.pack(order + code, value) + data[i + size:], \
        f"set {size}-byte integer at {i} to {value}"


def insert_bytes(rng, data, ctx):
    i = rng.randrange(len(data) + 1)
    n = rng.choice((1, 4, 16, 256))
    blob = bytes(rng.randrange(256) for _ in range(n)) if rng.random() < 0.5 \
        else bytes([rng.choice(INTERESTING_BYTES)]) * n
    return data[:i] + blob + data[i:], f"insert {n} bytes at {i}"


def delete_range(rng, data, ctx):
    i = rng.randrange(len(data))
    n = min(len(data) - i, rng.choice((1, 4, 16, 256, 4096)))
    return data[:i] + data[i + n:], f"delete {n} bytes at {i}"


def truncate(rng, data, ctx):
    n = rng.randrange(len(data))
    return data[:n], f"truncate to {n} of {len(data)} bytes"


def duplicate_chunk(rng, data, ctx):
    i = rng.randrange(len(data))
    n = min(len(data) - i, rng.choice((4, 16, 256, 4096)))
    times = rng.choice((1, 2, 16))
    return data[:i + n] + data[i:i + n] * times + data[i + n:], \
        f"duplicate {n} bytes at {i} x{times}"


def splice(rng, data, ctx):
    name, other = rng.choice(ctx.others)
    i, j = rng.randrange(len(data) + 1), rng.randrange(len(other) + 1)
    return data[:i] + other[j:], f"splice bytes 0..{i} with {name} from {j}"


BYTE_MUTATIONS = (flip_bits, set_bytes, set_integer, insert_bytes, delete_range, truncate,
                  duplicate_chunk, splice)


# --- JSON: values replaced in the parsed document, written back with raw tokens where JSON
# cannot express them (1e999, invalid UTF-8, deep nesting).

RAW_NUMBERS = (b"1e999", b"-1e999", b"1e308", b"-0", b"18446744073709551616",
               b"9223372036854775808", b"-9223372036854775809", b"4.9e-324", b"0.0", b"1e-320")
SIZE_VALUES = (0, -1, -32, 0.5, 1e9, 65537, 46340, 2147483647, 4294967296, 1e300)
OTHER_TYPES = (None, True, False, "", "x", [], {}, 0, -1, 3.5, [1, 2, 3], {"a": 1}, "1e999")
SIZE_KEY = re.compile(r"width|height|size|grid|slices|count|fx|fy|cx|cy|version|altitude|"
                      r"diameter|density|radius|seed", re.I)


class RawJson:
    """Raw bytes to splice into the serialised document in place of a value."""
    def __init__(self, raw: bytes):
        self.raw = raw


def json_paths(node, path=()) -> Iterable[tuple]:
    yield path
    if isinstance(node, dict):
        for key, value in node.items():
            yield from json_paths(value, path + (key,))
    elif isinstance(node, list):
        for i, value in enumerate(node):
            yield from json_paths(value, path + (i,))


def json_get(doc, path):
    for key in path:
        doc = doc[key]
    return doc


def json_dump(doc) -> bytes:
    raws: list[bytes] = []

    def encode(node):
        if isinstance(node, RawJson):
            raws.append(node.raw)
            return f"@@RAW{len(raws) - 1}@@"
        if isinstance(node, dict):
            return {key: encode(value) for key, value in node.items()}
        if isinstance(node, list):
            return [encode(value) for value in node]
        return node
    text = json.dumps(encode(doc), indent=2).encode()
    for i, raw in enumerate(raws):
        text = text.replace(f'"@@RAW{i}@@"'.encode(), raw)
    return text


def mutate_json(rng, data, ctx):
    try:
        doc = json.loads(data)
    except (ValueError, UnicodeDecodeError, RecursionError):  # deep nesting from a mutation
        return rng.choice(BYTE_MUTATIONS)(rng, data, ctx)
    paths = list(json_paths(doc))
    # A third of the time a top-level field ("format", "version", "views", ...): few, and each
    # decides how the rest is read.
    top = [p for p in paths if len(p) == 1]
    path = rng.choice(top if top and rng.random() < 0.3 else paths[1:] or paths)
    value = json_get(doc, path) if path else doc
    parent = json_get(doc, path[:-1]) if path else None
    where = "/".join(map(str, path)) or "(root)"
    key = path[-1] if path else None
    objects = [p for p in paths if isinstance(json_get(doc, p), dict)]
    op = rng.choice(("type", "type", "raw-number", "raw-number", "size", "unknown-key",
                     "misspell-key", "drop", "duplicate", "nesting", "invalid-utf8",
                     "empty-string", "long-string"))

    def put(new):
        nonlocal doc
        if parent is None:
            doc = new
        else:
            parent[key] = new

    if op == "type":
        new = rng.choice(OTHER_TYPES)
        put(new)
        description = f"{where} = {json.dumps(new)}"
    elif op == "raw-number":
        raw = rng.choice(RAW_NUMBERS[:2] if rng.random() < 0.5 else RAW_NUMBERS)   # +-1e999
        put(RawJson(raw))
        description = f"{where} = {raw.decode()}"
    elif op == "size":
        sized = [p for p in paths if p and isinstance(p[-1], str) and SIZE_KEY.search(p[-1])]
        if sized:
            path = rng.choice(sized)
            parent, key, where = json_get(doc, path[:-1]), path[-1], "/".join(map(str, path))
        new = rng.choice(SIZE_VALUES)
        if isinstance(json_get(doc, path), list):   # a size vector: one component
            target = json_get(doc, path)
            if target:
                parent, key = target, rng.randrange(len(target))
                where += f"/{key}"
        put(new)
        description = f"{where} = {new}"
    elif op in ("unknown-key", "misspell-key") and objects:
        obj_path = rng.choice(objects)
        obj = json_get(doc, obj_path)
        if op == "misspell-key" and obj:
            old = rng.choice(list(obj))
            i = rng.randrange(max(len(old), 1))
            new_key = old[:i] + old[i + 1:] if len(old) > 1 and rng.random() < 0.5 \
                else old[:i] + rng.choice("aeiorsx_") + old[i:]
            obj[new_key] = obj.pop(old)
            description = f"{'/'.join(map(str, obj_path))}: key {old!r} -> {new_key!r}"
        else:
            obj["unknown_key"] = rng.choice(OTHER_TYPES)
            description = f"{'/'.join(map(str, obj_path))}: unknown key added"
    elif op == "drop" and parent is not None:
        del parent[key]
        description = f"{where} removed"
    elif op == "duplicate" and isinstance(value, list) and value:
        times = rng.choice((2, 100, 10000))
        put(value * times)
        description = f"{where}: array repeated x{times}"
    elif op == "nesting":
        depth = rng.choice((100, 10000, 100000))
        put(RawJson(b"[" * depth + b"1" + b"]" * depth))
        description = f"{where} = [] nested {depth} deep"
    elif op == "invalid-utf8":
        bad = rng.choice((b"\xff\xfe", b"\xc3\x28", b"\xed\xa0\x80", b"\xe2\x82", b"\x80"))
        text = value.encode() if isinstance(value, str) else b"x"
        i = rng.randrange(len(text) + 1)
        put(RawJson(b'"' + text[:i] + bad + text[i:] + b'"'))
        description = f"{where}: invalid UTF-8 {bad!r} in a string"
    elif op == "empty-string":
        put("")
        description = f'{where} = ""'
    else:
        put("A" * rng.choice((256, 5000, 100000)))
        description = f"{where} = a long string"
    return json_dump(doc), "json: " + description


# --- Text files of tokens (CSV, COLMAP .txt): tokens, lines, encodings.

BAD_TOKENS = ("", "nan", "inf", "-inf", "1e999", "-1", "0", "4294967297",
              "18446744073709551617", "abc", "0x10", "1e308", "-0", "1,5", "\u0661", " ")


def mutate_text(rng, data, ctx):
    lines = data.split(b"\n")
    content = [i for i, line in enumerate(lines) if line.strip() and not line.startswith(b"#")]
    if not content:
        return rng.choice(BYTE_MUTATIONS)(rng, data, ctx)
    i = rng.choice(content)
    separator = b"," if b"," in lines[i] else b" "
    tokens = lines[i].split(separator)
    op = rng.choice(("token", "token", "token", "drop-token", "add-token", "drop-line",
                     "duplicate-line", "invalid-utf8", "bom", "crlf", "nul"))
    if op == "token":
        j = rng.randrange(len(tokens))
        new = rng.choice(BAD_TOKENS).encode()
        description = f"line {i + 1} token {j + 1}: {tokens[j]!r} -> {new!r}"
        tokens[j] = new
        lines[i] = separator.join(tokens)
    elif op == "drop-token":
        j = rng.randrange(len(tokens))
        del tokens[j]
        lines[i] = separator.join(tokens)
        description = f"line {i + 1}: token {j + 1} removed"
    elif op == "add-token":
        tokens.insert(rng.randrange(len(tokens) + 1), rng.choice(BAD_TOKENS).encode())
        lines[i] = separator.join(tokens)
        description = f"line {i + 1}: token added"
    elif op == "drop-line":
        del lines[i]
        description = f"line {i + 1} removed"
    elif op == "duplicate-line":
        lines.insert(i, lines[i])
        description = f"line {i + 1} duplicated"
    elif op == "invalid-utf8":
        lines[i] += b"\xff\xc3\x28"
        description = f"line {i + 1}: invalid UTF-8 appended"
    elif op == "bom":
        return b"\xef\xbb\xbf" + data, "text: byte-order mark prepended"
    elif op == "crlf":
        return data.replace(b"\n", b"\r\n"), "text: CRLF line ends"
    else:
        lines[i] = lines[i][:len(lines[i]) // 2] + b"\0" + lines[i][len(lines[i]) // 2:]
        description = f"line {i + 1}: NUL byte inserted"
    return b"\n".join(lines), "text: " + description


# --- Images: size fields set huge (checksums kept valid), data truncated, non-finite samples.

def png_with_ihdr(data: bytes, width: int, height: int, depth: Optional[int] = None) -> bytes:
    chunks = png_chunks(data)
    pos, _, ihdr, _ = chunks[0]
    fields = bytearray(ihdr)
    fields[0:8] = struct.pack(">II", width, height)
    if depth is not None:
        fields[8] = depth
    return data[:pos] + png_chunk(b"IHDR", bytes(fields)) + data[pos + 25:]


def mutate_png(rng, data, ctx):
    chunks = png_chunks(data)
    if not chunks or chunks[0][1] != b"IHDR":
        return rng.choice(BYTE_MUTATIONS)(rng, data, ctx)
    op = rng.choice(("huge", "huge", "zero", "depth", "short-idat", "idat-flip", "length"))
    if op == "huge":
        w, h = rng.choice(((46340, 46340), (65535, 65535), (1, 1 << 30), (1 << 31, 1),
                           (100000, 100000), (IMAGE_SIZE, 40000)))
        return png_with_ihdr(data, w, h), f"png: IHDR says {w}x{h} (CRC valid)"
    if op == "zero":
        w, h = rng.choice(((0, IMAGE_SIZE), (IMAGE_SIZE, 0), (0, 0)))
        return png_with_ihdr(data, w, h), f"png: IHDR says {w}x{h} (CRC valid)"
    if op == "depth":
        depth = rng.choice((0, 3, 7, 32, 255))
        return (png_with_ihdr(data, IMAGE_SIZE, IMAGE_SIZE, depth),
                f"png: bit depth {depth} (CRC valid)")
    idats = [c for c in chunks if c[1] == b"IDAT"]
    pos, _, payload, _ = rng.choice(idats)
    end = pos + 12 + len(payload)
    if op == "short-idat":
        keep = rng.randrange(len(payload))
        return data[:pos] + png_chunk(b"IDAT", payload[:keep]) + data[end:], \
            f"png: IDAT cut to {keep} of {len(payload)} bytes (CRC valid)"
    if op == "idat-flip":
        flipped = bytearray(payload)
        i = rng.randrange(len(flipped))
        flipped[i] ^= 1 << rng.randrange(8)
        return data[:pos] + png_chunk(b"IDAT", bytes(flipped)) + data[end:], \
            f"png: IDAT byte {i} flipped (CRC valid)"
    length = rng.choice((0x7FFFFFFF, 0xFFFFFFFF, len(payload) + 1000))
    return data[:pos] + struct.pack(">I", length) + data[pos + 4:], f"png: IDAT length {length}"


def tiff_set(data: bytes, tiff: Tiff, tag: int, value: int) -> bytes:
    where, kind = tiff.tag_positions[tag]
    if kind == 3:   # a SHORT field holds at most 65535
        value = min(value, 0xFFFF)
    packed = struct.pack(tiff.order + ("H" if kind == 3 else "I"), value)
    return data[:where] + packed + data[where + len(packed):]


def mutate_tiff(rng, data, ctx):
    try:
        tiff = Tiff(data)
    except (ValueError, struct.error):
        return rng.choice(BYTE_MUTATIONS)(rng, data, ctx)
    ops = ["huge", "huge", "truncate-data", "strip-past-end", "bits", "samples"]
    if tiff.compression == 1 and tiff.sample_format == 3:
        ops += ["nonfinite", "nonfinite"]
    geo_tags = [t for t in (33550, 33922) if t in tiff.tag_positions]   # pixel scale, tiepoint
    if geo_tags:
        ops += ["geo", "geo"]
    op = rng.choice(ops)
    if op == "geo":   # a DEM's placement: a double of ModelPixelScale or ModelTiepoint
        tag = rng.choice(geo_tags)
        where, _ = tiff.tag_positions[tag]
        (where,) = struct.unpack(tiff.order + "I", data[where:where + 4])   # doubles: an offset
        k = rng.randrange(3 if tag == 33550 else 6)
        value = rng.choice((0.0, -1.0, math.nan, math.inf, -math.inf, 1e300, -1e300, 1e-300,
                            5e6, 1e15))
        at = where + 8 * k
        return data[:at] + struct.pack(tiff.order + "d", value) + data[at + 8:], \
            f"geotiff: {'ModelPixelScale' if tag == 33550 else 'ModelTiepoint'}[{k}] = {value}"
    if op == "huge" and 256 in tiff.tag_positions and 257 in tiff.tag_positions:
        w, h = rng.choice(((30000, 30000), (65535, 65535), (1, 1 << 30), (IMAGE_SIZE, 100000)))
        data = tiff_set(tiff_set(data, tiff, 256, w), tiff, 257, h)
        return data, f"tiff: size tags say {w}x{h}"
    if op == "truncate-data" and tiff.offsets:
        cut = tiff.offsets[-1] + rng.randrange(max(tiff.counts[-1], 1))
        return data[:cut], f"tiff: truncated inside the image data at {cut} of {len(data)} bytes"
    if op == "strip-past-end" and 279 in tiff.tag_positions:
        count = rng.choice((len(data), 0x7FFFFFFF, 0xFFFFFFFF))
        return tiff_set(data, tiff, 279, count), f"tiff: strip byte count {count}"
    if op == "bits" and 258 in tiff.tag_positions:
        bits = rng.choice((0, 1, 7, 12, 24, 64, 65535))
        return tiff_set(data, tiff, 258, bits), f"tiff: bits per sample {bits}"
    if op == "samples" and 277 in tiff.tag_positions:
        spp = rng.choice((0, 2, 5, 255, 65535))
        return tiff_set(data, tiff, 277, spp), f"tiff: samples per pixel {spp}"
    if op == "nonfinite" and tiff.offsets:
        value = rng.choice((math.nan, math.inf, -math.inf))
        n = tiff.counts[0] // 4
        i = tiff.offsets[0] + 4 * rng.randrange(max(n, 1))
        return data[:i] + struct.pack(tiff.order + "f", value) + data[i + 4:], \
            f"tiff: float sample at byte {i} set to {value}"
    return rng.choice(BYTE_MUTATIONS)(rng, data, ctx)


def mutate_jpeg(rng, data, ctx):
    sof = next((m.start() for m in re.finditer(b"\xff[\xc0-\xc3]", data)), None)
    sos = data.find(b"\xff\xda")
    if sof is None or sos < 0:
        return rng.choice(BYTE_MUTATIONS)(rng, data, ctx)
    if rng.random() < 0.5:
        w, h = rng.choice(((65500, 65500), (0, IMAGE_SIZE), (IMAGE_SIZE, 0), (40000, 30000)))
        return data[:sof + 5] + struct.pack(">HH", h, w) + data[sof + 9:], f"jpeg: SOF says {w}x{h}"
    cut = rng.randrange(sos, len(data) - 2)
    return data[:cut], f"jpeg: truncated in the scan at {cut} of {len(data)} bytes"


def mutate_exr(rng, data, ctx):
    try:
        attributes, header_end = exr_header(data)
        _, window_at, _ = attributes["dataWindow"]
    except (ValueError, KeyError, struct.error):
        return rng.choice(BYTE_MUTATIONS)(rng, data, ctx)
    if rng.random() < 0.5:
        x1, y1 = rng.choice(((29999, 29999), (65535, 65535), (-5, IMAGE_SIZE - 1),
                             (IMAGE_SIZE - 1, 1 << 30)))
        return data[:window_at + 8] + struct.pack("<ii", x1, y1) + data[window_at + 16:], \
            f"exr: dataWindow max ({x1}, {y1})"
    cut = rng.randrange(header_end, len(data))
    return data[:cut], f"exr: truncated at {cut} of {len(data)} bytes"


# --- EXIF GPS and DJI XMP tags of a frame (import-telemetry without a log).

GPS_RATIONALS = ((0, 1), (1, 0), (0, 0), (0xFFFFFFFF, 1), (1, 0xFFFFFFFF), (90, 1), (91, 1),
                 (181, 1), (0x7FFFFFFF, 0x7FFFFFFF), (60, 1), (3600 * 10000, 10000))
XMP_VALUES = (b"nan", b"+nan", b"inf", b"-inf", b"1e999", b"", b" ", b"abc", b"+-1", b"--90",
              b"1,5", b"361", b"-361", b"90", b"-180.5", b"+1e308", b"0x10", b"1e-400",
              b"\xff\xfe", b"A" * 5000)


def exif_entries(data: bytes) -> tuple[int, list[tuple[int, int, int, int, int]]]:
    """(offset of the TIFF header, [(entry offset, tag, type, count, value/offset)]) of the GPS
    IFD of the first APP1 Exif segment; raises ValueError when there is none to follow."""
    at = data.find(b"Exif\0\0")
    if at < 0:
        raise ValueError("no Exif segment")
    base = at + 6
    order = "<" if data[base:base + 2] == b"II" else ">"
    (ifd0,) = struct.unpack(order + "I", data[base + 4:base + 8])
    (count,) = struct.unpack(order + "H", data[base + ifd0:base + ifd0 + 2])
    gps = None
    for i in range(count):
        entry = base + ifd0 + 2 + 12 * i
        tag, _, _, value = struct.unpack(order + "HHII", data[entry:entry + 12])
        if tag == 0x8825:
            gps = value
    if gps is None:
        raise ValueError("no GPS IFD")
    (count,) = struct.unpack(order + "H", data[base + gps:base + gps + 2])
    entries = []
    for i in range(count):
        entry = base + gps + 2 + 12 * i
        entries.append((entry, *struct.unpack(order + "HHII", data[entry:entry + 12])))
    return base, entries


def mutate_exif(rng, data, ctx):
    """GPS tags: a rational's numerator or denominator, a reference letter, an entry's type,
    count or offset; XMP: a DJI value, a missing closing tag, the packet cut; else the JPEG's
    own mutations."""
    op = rng.choice(("rational", "rational", "ref", "entry", "xmp", "xmp", "xmp-close", "jpeg"))
    try:
        base, entries = exif_entries(data)
    except (ValueError, struct.error):
        op = "xmp" if op != "jpeg" else op
        entries, base = [], 0
    names = {0: "GPSVersionID", 1: "GPSLatitudeRef", 2: "GPSLatitude", 3: "GPSLongitudeRef",
             4: "GPSLongitude", 5: "GPSAltitudeRef", 6: "GPSAltitude"}
    rationals = [e for e in entries if e[2] == 5]
    if op == "rational" and rationals:
        entry, tag, _, count, offset = rng.choice(rationals)
        k = rng.randrange(max(min(count, 3), 1))
        n, d = rng.choice(GPS_RATIONALS)
        at = base + offset + 8 * k
        if at + 8 <= len(data):
            return data[:at] + struct.pack("<II", n, d) + data[at + 8:], \
                f"exif: {names.get(tag, tag)}[{k}] = {n}/{d}"
    refs = [e for e in entries if e[1] in (1, 3)]
    if op == "ref" and refs:
        entry, tag, _, _, _ = rng.choice(refs)
        letter = rng.choice((b"X", b"n", b"S", b"W", b"\0", b"\xff", b"NS"))
        value = letter.ljust(4, b"\0")[:4]
        return data[:entry + 8] + value + data[entry + 12:], \
            f"exif: {names.get(tag, tag)} = {letter!r}"
    if op == "entry" and entries:
        entry, tag, kind, count, offset = rng.choice(entries)
        field = rng.choice(("type", "count", "offset"))
        if field == "type":
            value, at, size = rng.choice((0, 2, 3, 7, 12, 13, 0xFFFF)), entry + 2, "H"
        elif field == "count":
            value, at, size = rng.choice((0, 2, 255, 0x7FFFFFFF, 0xFFFFFFFF)), entry + 4, "I"
        else:
            value, at, size = rng.choice((0, len(data), 0x7FFFFFFF, 0xFFFFFFF0)), entry + 8, "I"
        return data[:at] + struct.pack("<" + size, value) + data[at + struct.calcsize(size):], \
            f"exif: {names.get(tag, tag)} {field} = {value}"
    values = list(re.finditer(rb'(drone-dji:[A-Za-z]+)="([^"]*)"', data))
    if op == "xmp" and values:
        match = rng.choice(values)
        new = rng.choice(XMP_VALUES)
        return data[:match.start(2)] + new + data[match.end(2):], \
            f"xmp: {match.group(1).decode()} = {new[:20]!r}"
    close = data.find(b"</x:xmpmeta>")
    if op == "xmp-close" and close >= 0:
        if rng.random() < 0.5:
            return data[:close] + data[close + 12:], "xmp: closing </x:xmpmeta> removed"
        cut = rng.randrange(data.find(b"<x:xmpmeta"), close)
        return data[:cut], f"xmp: file cut inside the packet at {cut}"
    return mutate_jpeg(rng, data, ctx)


# --- Meshes: PLY headers (counts, types, formats); OBJ is text (mutate_text).

PLY_COUNTS = (0, 1, 2, 0x7FFFFFFF, 0xFFFFFFFF, 4294967296, 1 << 40, -1, 100000000)
PLY_TYPES = (b"char", b"uchar", b"short", b"int", b"uint", b"float", b"double", b"int64",
             b"float16", b"list", b"")


def mutate_ply(rng, data, ctx):
    end = data.find(b"end_header\n")
    if not data.startswith(b"ply") or end < 0:
        return rng.choice(BYTE_MUTATIONS)(rng, data, ctx)
    header, body = data[:end], data[end:]
    lines = header.split(b"\n")
    op = rng.choice(("count", "count", "type", "format", "property", "body"))
    elements = [i for i, line in enumerate(lines) if line.startswith(b"element ")]
    properties = [i for i, line in enumerate(lines) if line.startswith(b"property ")]
    if op == "count" and elements:
        i = rng.choice(elements)
        words = lines[i].split(b" ")
        count = rng.choice(PLY_COUNTS)
        lines[i] = b" ".join(words[:2] + [str(count).encode()])
        return b"\n".join(lines) + body, f"ply: {words[1].decode()} count {count}"
    if op == "type" and properties:
        i = rng.choice(properties)
        words = lines[i].split(b" ")
        j = rng.randrange(1, len(words) - 1) if len(words) > 2 else 1
        new = rng.choice(PLY_TYPES)
        description = f"ply: line {i + 1} type {words[j][:10]!r} -> {new!r}"
        words[j] = new
        lines[i] = b" ".join(words)
        return b"\n".join(lines) + body, description
    if op == "format":
        new = rng.choice((b"format binary_big_endian 1.0", b"format ascii 2.0", b"format ascii",
                          b"format binary_little_endian 1.0", b"format ascii 1.0"))
        lines = [new if line.startswith(b"format") else line for line in lines]
        return b"\n".join(lines) + body, f"ply: {new.decode()}"
    if op == "property" and properties:
        i = rng.choice(properties)
        if rng.random() < 0.5:
            del lines[i]
            return b"\n".join(lines) + body, f"ply: property line {i + 1} removed"
        lines.insert(i, lines[i])
        return b"\n".join(lines) + body, f"ply: property line {i + 1} repeated"
    if b"format ascii" in header:
        mutated, description = mutate_text(rng, body[len(b"end_header\n"):], ctx)
        return header + b"end_header\n" + mutated, "ply body: " + description
    return rng.choice(BYTE_MUTATIONS)(rng, data, ctx)


# --- The plan's --vertices argument: X,Y;X,Y;...

VERTEX_NUMBERS = ("nan", "inf", "-inf", "1e999", "1e300", "-1e300", "1e15", "5e6", "0", "-0",
                  "", " ", "abc", "1,5", "0x10", "1e-320", "4.9e-324", "500000.0000000001")


def mutate_vertices(rng, data, ctx):
    try:
        text = data.decode()
        vertices = [pair.split(",") for pair in text.split(";")]
    except UnicodeDecodeError:
        return rng.choice(BYTE_MUTATIONS)(rng, data, ctx)
    op = rng.choice(("number", "number", "extreme", "drop", "duplicate", "repeat", "swap",
                     "separator", "collinear"))
    i = rng.randrange(len(vertices))
    if op == "number" and vertices[i]:
        j = rng.randrange(len(vertices[i]))
        vertices[i][j] = rng.choice(VERTEX_NUMBERS)
        description = f"vertex {i} coordinate {j} = {vertices[i][j]!r}"
    elif op == "extreme":
        scale = rng.choice((1e3, 1e6, 1e9, 1e12, -1.0))
        vertices = [[f"{float(v) * scale!r}" if _is_float(v) else v for v in pair]
                    for pair in vertices]
        description = f"every coordinate x {scale:g}"
    elif op == "drop" and len(vertices) > 1:
        del vertices[i]
        description = f"vertex {i} removed"
    elif op == "duplicate":
        vertices.insert(i, list(vertices[i]))
        description = f"vertex {i} repeated"
    elif op == "repeat":
        times = rng.choice((10, 100, 1000))   # 1000: about 80 kB, under Linux's 128 kB argument
        vertices = vertices * times
        description = f"the polygon repeated x{times}"
    elif op == "swap" and len(vertices) > 3:
        vertices[0], vertices[2] = vertices[2], vertices[0]
        description = "vertices 0 and 2 swapped (self-intersecting)"
    elif op == "collinear":
        vertices = [[str(k), str(k)] for k in range(len(vertices))]
        description = "every vertex on one line"
    else:
        separator = rng.choice((";;", ";", ",", " ", "\n", ""))
        return (separator.join(",".join(pair) for pair in vertices)).encode(), \
            f"vertices joined by {separator!r}"
    return ";".join(",".join(pair) for pair in vertices).encode(), "vertices: " + description


def _is_float(text: str) -> bool:
    try:
        return math.isfinite(float(text))
    except ValueError:
        return False


def mutate_colmap_binary(rng, data, ctx):
    count = rng.choice((0, 1 << 32, 1 << 40, (1 << 63) - 1, (1 << 64) - 1, 1000000))
    return struct.pack("<Q", count) + data[8:], f"colmap: leading count {count}"


def structural_mutation(name: str, data: bytes) -> Optional[Callable]:
    """The structural mutation for a file's type, by magic or extension (None: bytes only)."""
    suffix = Path(name).suffix.lower()
    if name.startswith("exif/"):
        return mutate_exif
    if data.startswith(b"ply"):
        return mutate_ply
    if suffix == ".vertices":
        return mutate_vertices
    if data.startswith(b"\x89PNG"):
        return mutate_png
    if data[:4] in (b"II*\0", b"MM\0*"):
        return mutate_tiff
    if data.startswith(b"\xff\xd8"):
        return mutate_jpeg
    if data.startswith(b"v/1\x01"):
        return mutate_exr
    if suffix == ".json":
        return mutate_json
    if suffix in (".csv", ".txt", ".obj"):
        return mutate_text
    if suffix == ".bin":
        return mutate_colmap_binary
    return None


def mutate(rng: random.Random, data: bytes, ctx: MutationContext) -> tuple[bytes, str]:
    """One or two mutations: structural for the file's type about half of the time."""
    descriptions = []
    for _ in range(2 if rng.random() < 0.2 else 1):
        structural = structural_mutation(ctx.name, data)
        if not data:
            data, description = insert_bytes(rng, data, ctx)
        elif structural and rng.random() < 0.55:
            try:
                data, description = structural(rng, data, ctx)
            except (struct.error, ValueError, IndexError):   # a layout already broken
                data, description = rng.choice(BYTE_MUTATIONS)(rng, data, ctx)
        else:
            data, description = rng.choice(BYTE_MUTATIONS)(rng, data, ctx)
        descriptions.append(description)
    return data, "; ".join(descriptions)


# =============================================================================================
# Targets.

@dataclasses.dataclass(frozen=True)
class Target:
    """One reader exercised through the CLI (argv) or through Python (code run by the worker).

    `files`: glob patterns (corpus-relative) of the files it reads that may be mutated; a case
    picks a pattern, then a file. In `argv` and `code`, {file} is the mutated file's path, {name}
    its base name and {aos_render} the CLI under test; paths are relative to the case folder,
    whose `in/` holds the corpus and `out/` the outputs.
    """
    name: str
    files: tuple[str, ...]
    argv: tuple[str, ...] = ()
    code: str = ""                      # Python: statements run with `aos` imported; `result`
    outputs: tuple[str, ...] = ()       # paths that must exist after a success
    output_file: Optional[str] = None   # the single output file (for the output-is-input case)
    stdout_json: bool = False           # stdout is one JSON object to check
    # The word a refusal must name; default: the mutated file's base name. For a target whose
    # input is a command-line argument ({text}: the mutated file's bytes as that argument),
    # the option or field it fills; alternatives separated by "|" (a plan made too large by a
    # mutated vertex is rightly refused by the plan's size bounds, naming those options).
    error_name: str = ""
    viewer: bool = False                # a request to the viewer server (see ViewerServer)
    # Whether the command decodes the pixels of the images it reads: a command that reads only
    # their headers and tags (import-telemetry) may accept an image whose pixel data is damaged.
    decodes_pixels: bool = True

    @property
    def kind(self) -> str:
        return "viewer" if self.viewer else "python" if self.code else "cli"

    @property
    def text_argument(self) -> bool:
        return any("{text}" in a for a in self.argv)

    def format(self, template: str, file: str, aos_render: str, text: str = "") -> str:
        return template.format(file=file, name=Path(file).name, aos_render=aos_render, text=text)


LF = "in/sim/lightfield.json"
JKU = "in/jku/poses/poses.json"
STACK_FILES = ("stack/stack.json", "stack/slice_*.tif", "stack/count_*.tif")
IMAGES = ("images/*",)
QUIET = "-q"

# A float32 integral image of the simulated light field (the surface and mask targets).
SURFACE_RENDER = ("{aos_render}", "integral", LF, *VIRTUAL_CAMERA, "--sample-type", "float32",
                  "-o", "out/integral.tif")
# A polygon flight in UTM zone 33 (the plan targets; the polygon or the DEM is the input).
PLAN = ("{aos_render}", "plan", "--shape", "polygon", "--crs", "EPSG:32633", "--spacing-m", "10",
        "--along-spacing-m", "10", "--altitude-m", "30")
PLAN_VERTICES = "500000,5300000;500060,5300000;500060,5300040;500000,5300040"

TARGETS = (
    Target("integral-aos", ("sim/lightfield.json", "sim/views/*.png"),
           argv=("{aos_render}", "integral", LF, *VIRTUAL_CAMERA, "--sample-type", "float32",
                 "-o", "out/integral.tif", "--count", "out/count.tif", QUIET),
           outputs=("out/integral.tif", "out/count.tif"), output_file="out/integral.tif"),
    Target("integral-jku", ("jku/poses/poses.json", "jku/images/*.png"),
           argv=("{aos_render}", "integral", JKU, "--frames-fov-deg", str(FRAMES_FOV_DEG),
                 *VIRTUAL_CAMERA, "--sample-type", "float32", "-o", "out/integral.tif", QUIET),
           outputs=("out/integral.tif",), output_file="out/integral.tif"),
    Target("simulate", ("scene.json",),
           argv=("{aos_render}", "simulate", "in/scene.json", "-o", "out/sim", QUIET),
           outputs=("out/sim/lightfield.json",)),
    Target("merge", STACK_FILES,
           argv=("{aos_render}", "merge", "in/stack", "-o", "out/merge", QUIET),
           outputs=("out/merge/all_in_focus.tif",)),
    Target("import-colmap-txt", ("colmap_txt/*.txt",),
           argv=("{aos_render}", "import-colmap", "in/colmap_txt", "--images-dir", "in/sim/views",
                 "-o", "out/lf.json"),
           outputs=("out/lf.json",), output_file="out/lf.json"),
    Target("import-colmap-bin", ("colmap_bin/*.bin",),
           argv=("{aos_render}", "import-colmap", "in/colmap_bin", "--images-dir", "in/sim/views",
                 "-o", "out/lf.json"),
           outputs=("out/lf.json",), output_file="out/lf.json"),
    Target("import-colmap-positions", ("positions.csv",),
           argv=("{aos_render}", "import-colmap", "in/colmap_txt", "--images-dir", "in/sim/views",
                 "--positions-file", "in/positions.csv", "-o", "out/lf.json"),
           outputs=("out/lf.json",), output_file="out/lf.json"),
    Target("rectify-camera", ("camera.json",),
           argv=("{aos_render}", "rectify", "in/images/gray8.png", "--camera", "in/camera.json",
                 "--rectified-fov-deg", "40", "-o", "out/rect", QUIET),
           outputs=("out/rect/gray8.png",)),
    Target("rectify-frame", IMAGES,
           argv=("{aos_render}", "rectify", "{file}", "--camera", "in/camera.json",
                 "--rectified-fov-deg", "40", "-o", "out/rect", QUIET),
           outputs=("out/rect/{name}",)),
    Target("metrics", IMAGES,
           argv=("{aos_render}", "metrics", "{file}", "in/ref/{name}", "--json"),
           stdout_json=True),
    Target("integral-surface-obj", ("surface/terrain.obj",),
           argv=(*SURFACE_RENDER, "--focal-surface", "{file}", QUIET),
           outputs=("out/integral.tif",), output_file="out/integral.tif"),
    Target("integral-surface-ply", ("surface/terrain.ply", "surface/terrain_binary.ply"),
           argv=(*SURFACE_RENDER, "--focal-surface", "{file}", QUIET),
           outputs=("out/integral.tif",), output_file="out/integral.tif"),
    Target("integral-surface-dem", ("surface/dem.tif",),
           argv=(*SURFACE_RENDER, "--focal-surface", "{file}", QUIET),
           outputs=("out/integral.tif",), output_file="out/integral.tif"),
    Target("integral-mask", ("mask.png",),
           argv=(*SURFACE_RENDER, "--mask", "in/mask.png", QUIET),
           outputs=("out/integral.tif",), output_file="out/integral.tif"),
    Target("integral-mask-dir", ("masks/*.png",),
           argv=(*SURFACE_RENDER, "--mask-dir", "in/masks", QUIET),
           outputs=("out/integral.tif",)),
    Target("import-telemetry-csv", ("telemetry/*.csv",),
           argv=("{aos_render}", "import-telemetry", "in/sim/views", "--telemetry-file", "{file}",
                 "--frames-fov-deg", str(FRAMES_FOV_DEG), "--frame-interval-s", "1",
                 "-o", "out/lf.json", QUIET),
           outputs=("out/lf.json",), output_file="out/lf.json"),
    Target("import-telemetry-exif", ("exif/*.jpg",),
           argv=("{aos_render}", "import-telemetry", "in/exif", "--frames-fov-deg",
                 str(FRAMES_FOV_DEG), "-o", "out/lf.json", QUIET),
           outputs=("out/lf.json",), output_file="out/lf.json", decodes_pixels=False),
    Target("plan-vertices", ("plan/polygon.vertices",),
           argv=(*PLAN, "--vertices", "{text}", "--csv", "out/plan.csv", "--geojson",
                 "out/plan.geojson", "--kml", "out/plan.kml", QUIET),
           outputs=("out/plan.csv", "out/plan.geojson", "out/plan.kml"), error_name="vertices|--battery-min|--max-waypoints"),
    Target("plan-dem", ("plan/dem.tif",),
           argv=(*PLAN, "--vertices", PLAN_VERTICES, "--dem", "in/plan/dem.tif", "--csv",
                 "out/plan.csv", "--geojson", "out/plan.geojson", QUIET),
           outputs=("out/plan.csv", "out/plan.geojson")),
    Target("viewer-http", ("viewer/render.json", "viewer/map.json", "viewer/pick.json",
                           "viewer/export.json", "viewer/command.json"), viewer=True),
    Target("viewer-ws", ("viewer/ws_*.json",), viewer=True),
    Target("py-load-lightfield-aos", ("sim/lightfield.json", "sim/views/*.png"),
           code=f"result = aos.load_lightfield({LF!r})"),
    Target("py-load-lightfield-jku", ("jku/poses/poses.json", "jku/images/*.png"),
           code=f"result = aos.load_lightfield({JKU!r}, fov_deg={FRAMES_FOV_DEG})"),
    Target("py-read-image", IMAGES + ("sim/views/0000.png", "stack/slice_0000.tif"),
           code="result = aos.read_image({file!r})"),
    Target("py-read-camera-file", ("camera.json",),
           code="result = aos.read_camera_file('in/camera.json')"),
    Target("py-import-colmap-txt", ("colmap_txt/*.txt", "positions.csv"),
           code="result = aos.import_colmap('in/colmap_txt', 'in/sim/views', "
                "positions_file='in/positions.csv')"),
    Target("py-import-colmap-bin", ("colmap_bin/*.bin",),
           code="result = aos.import_colmap('in/colmap_bin', 'in/sim/views')"),
    Target("py-read-positions", ("positions.csv",),
           code="result = aos.read_positions('in/positions.csv')"),
    Target("py-simulate", ("scene.json",),
           code="result = aos.simulate('in/scene.json', 'out/sim')",
           outputs=("out/sim/lightfield.json",)),
    Target("py-focal-stack", STACK_FILES,
           code="result = aos.merge_focal_stack(aos.read_focal_stack('in/stack'))"),
)


def select_targets(spec: Optional[str]) -> list[Target]:
    """Targets named in a comma list; a name also selects its family ('integral' ->
    integral-aos, integral-jku; 'py' -> every Python target)."""
    if not spec:
        return list(TARGETS)
    wanted = [s.strip() for s in spec.split(",") if s.strip()]

    def selects(name: str, word: str) -> bool:
        return name == word or name.startswith(word + "-")
    chosen = [t for t in TARGETS if any(selects(t.name, w) for w in wanted)]
    unknown = [w for w in wanted if not any(selects(t.name, w) for t in TARGETS)]
    if unknown or not chosen:
        raise SystemExit(f"fuzz.py: unknown targets {unknown}; see --list-targets")
    return chosen


# =============================================================================================
# Running one process: limits, timeout, peak memory.

@dataclasses.dataclass
class Limits:
    timeout_s: float = 10.0
    address_space_mb: int = 4096    # RLIMIT_AS of every child
    rss_mb: int = 1024              # peak resident memory above this is a failure (memory)
    term_grace_s: float = 2.0       # after the timeout's SIGTERM, seconds until SIGKILL


def limit_address_space(megabytes: int) -> Callable[[], None]:
    def apply() -> None:
        size = megabytes << 20
        resource.setrlimit(resource.RLIMIT_AS, (size, size))
        resource.setrlimit(resource.RLIMIT_CORE, (0, 0))
    return apply


def child_environment(python_path: Optional[str]) -> dict[str, str]:
    env = dict(os.environ, **CHILD_ENV)
    if python_path:
        env["PYTHONPATH"] = os.pathsep.join(filter(None, [python_path, env.get("PYTHONPATH")]))
    return env


@dataclasses.dataclass
class Execution:
    """What one run did: the exit, the streams, the resources."""
    returncode: Optional[int] = None     # exit status (None when killed by a signal)
    signal: Optional[int] = None
    timed_out: bool = False
    ignored_sigterm: bool = False        # timed out and still running term_grace_s after SIGTERM
    stdout: str = ""
    stderr: str = ""
    peak_rss_kb: int = 0
    wall_s: float = 0.0
    # Python targets: the exception raised (None when the code returned)
    exception_type: Optional[str] = None
    exception_message: str = ""
    result_defect: Optional[str] = None  # a non-finite value in the returned arrays


def terminate(pid: int, grace_s: float) -> tuple[int, resource.struct_rusage, bool]:
    """Stops the process `pid` (a session leader) as a user would: SIGTERM to its process
    group, then, if it is still running after grace_s seconds, SIGKILL. Returns its wait status,
    its resource usage and whether SIGKILL was needed (it ignored or outlived SIGTERM)."""
    try:
        os.killpg(pid, signal.SIGTERM)
    except ProcessLookupError:
        pass
    deadline = time.monotonic() + grace_s
    while time.monotonic() < deadline:
        reaped, status, usage = os.wait4(pid, os.WNOHANG)
        if reaped:
            return status, usage, False
        time.sleep(0.01)
    try:
        os.killpg(pid, signal.SIGKILL)
    except ProcessLookupError:
        pass
    _, status, usage = os.wait4(pid, 0)
    return status, usage, True


def run_process(argv: list[str], cwd: Path, limits: Limits, env: dict[str, str],
                log_dir: Path) -> Execution:
    """Runs argv in cwd with stdout/stderr in files, the address-space limit, and after the
    timeout SIGTERM to its process group, then SIGKILL if it has not ended within
    limits.term_grace_s (terminate); the peak RSS comes from wait4."""
    out_path, err_path = log_dir / "stdout", log_dir / "stderr"
    start = time.monotonic()
    with open(out_path, "wb") as out, open(err_path, "wb") as err:
        process = subprocess.Popen(argv, cwd=cwd, stdin=subprocess.DEVNULL, stdout=out,
                                   stderr=err, env=env, start_new_session=True,
                                   preexec_fn=limit_address_space(limits.address_space_mb))
    execution = Execution()
    deadline = start + limits.timeout_s
    delay = 0.002
    while True:
        pid, status, usage = os.wait4(process.pid, os.WNOHANG)
        if pid:
            break
        if time.monotonic() > deadline:
            execution.timed_out = True
            status, usage, execution.ignored_sigterm = terminate(process.pid, limits.term_grace_s)
            break
        time.sleep(delay)
        delay = min(delay * 1.5, 0.02)
    process.returncode = os.waitstatus_to_exitcode(status)   # reaped here, not by Popen
    try:   # leftover children of the process group
        os.killpg(process.pid, signal.SIGKILL)
    except (ProcessLookupError, PermissionError):
        pass
    execution.wall_s = time.monotonic() - start
    if os.WIFSIGNALED(status):
        execution.signal = os.WTERMSIG(status)
    else:
        execution.returncode = os.WEXITSTATUS(status)
    execution.peak_rss_kb = usage.ru_maxrss
    execution.stdout = out_path.read_bytes().decode("utf-8", "replace")
    execution.stderr = err_path.read_bytes().decode("utf-8", "replace")
    return execution


class PythonWorker:
    """A `fuzz.py --worker` process that imports aos once and runs one case's code per request.
    A crash or a hang kills it; it is started again for the next case."""

    def __init__(self, python_path: Optional[str], limits: Limits):
        self.python_path, self.limits = python_path, limits
        self.process: Optional[subprocess.Popen] = None

    def start(self) -> None:
        self.process = subprocess.Popen(
            [sys.executable, os.path.abspath(__file__), "--worker"],
            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL,
            env=child_environment(self.python_path), start_new_session=True,
            preexec_fn=limit_address_space(self.limits.address_space_mb))
        hello = self._read_line(60.0)
        if not hello or json.loads(hello).get("ready") is not True:
            self.stop()
            raise RuntimeError(f"the Python worker did not start (import aos failed?): {hello!r}")

    def _read_line(self, timeout: float) -> Optional[str]:
        """The next line from the worker; None if none came within `timeout` seconds."""
        assert self.process and self.process.stdout
        ready, _, _ = select.select([self.process.stdout], [], [], timeout)
        if not ready:
            return None
        return self.process.stdout.readline().decode()   # "" at the end of the stream

    def stop(self, grace_s: float = 0.0) -> tuple[Optional[int], int, bool]:
        """Ends the worker: SIGKILL, or with grace_s > 0 SIGTERM first (terminate). Returns
        (the signal that ended it or None, its peak RSS in kB, whether SIGKILL was needed after
        a SIGTERM)."""
        if not self.process:
            return None, 0, False
        ignored = False
        if grace_s > 0:
            status, usage, ignored = terminate(self.process.pid, grace_s)
        else:
            try:
                os.killpg(self.process.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
            _, status, usage = os.wait4(self.process.pid, 0)
        self.process.returncode = os.waitstatus_to_exitcode(status)
        for stream in (self.process.stdin, self.process.stdout):
            stream.close()
        self.process = None
        return (os.WTERMSIG(status) if os.WIFSIGNALED(status) else None), usage.ru_maxrss, ignored

    def run(self, code: str, cwd: Path, log_dir: Path) -> Execution:
        if not self.process:
            self.start()
        assert self.process and self.process.stdin
        request = {"code": code, "cwd": str(cwd), "stderr": str(log_dir / "stderr")}
        start = time.monotonic()
        execution = Execution()
        try:
            self.process.stdin.write((json.dumps(request) + "\n").encode())
            self.process.stdin.flush()
            line = self._read_line(self.limits.timeout_s)
        except BrokenPipeError:
            line = ""
        execution.wall_s = time.monotonic() - start
        if line:
            reply = json.loads(line)
            execution.returncode = 0 if reply["exception"] is None else 1
            execution.exception_type = reply["exception"]
            execution.exception_message = reply["message"]
            execution.result_defect = reply["defect"]
            execution.peak_rss_kb = reply["peak_rss_kb"]
        else:
            execution.timed_out = line is None   # None: no answer in time; "": the worker died
            # A worker that exits instead of answering (e.g. abort() after a message, or
            # os._exit) is reported by its signal, or as exit status 1.
            killed_signal, execution.peak_rss_kb, execution.ignored_sigterm = self.stop(
                self.limits.term_grace_s if execution.timed_out else 0.0)
            if not execution.timed_out:
                execution.signal = killed_signal
                execution.returncode = None if killed_signal else 1
        stderr_path = log_dir / "stderr"
        execution.stderr = stderr_path.read_bytes().decode("utf-8", "replace") \
            if stderr_path.exists() else ""
        return execution


def worker_main() -> None:
    """The Python worker: reads {"code", "cwd", "stderr"} requests, one per line, runs the code
    with aos imported (fds 1 and 2 go to the case's stderr file), and answers one JSON line."""
    import traceback
    import numpy as np
    protocol = os.fdopen(os.dup(1), "w")
    os.dup2(2, 1)
    import aos

    def peak_rss_kb() -> int:
        with open("/proc/self/status") as status:
            return next(int(line.split()[1]) for line in status if line.startswith("VmHWM"))

    def non_finite(value, depth=0) -> Optional[str]:
        """A NaN or infinity in the float arrays reachable from a result."""
        if isinstance(value, np.ndarray):
            if value.dtype.kind == "f" and not np.isfinite(value).all():
                return f"a {value.shape} {value.dtype} array with non-finite values"
            return None
        if depth > 5 or value is None or isinstance(value, (str, bytes, int, float, bool)):
            return None
        if isinstance(value, (list, tuple)):
            items = value
        elif isinstance(value, dict):
            items = list(value.values())
        else:
            items = []
            for name in dir(value):
                if name.startswith("_"):
                    continue
                try:
                    attribute = getattr(value, name)
                except Exception:   # a property that raises for this object
                    continue
                if not callable(attribute):
                    items.append(attribute)
        for item in items:
            found = non_finite(item, depth + 1)
            if found:
                return found
        return None

    protocol.write(json.dumps({"ready": True}) + "\n")
    protocol.flush()
    saved_stderr = os.dup(2)
    for line in sys.stdin:
        request = json.loads(line)
        os.chdir(request["cwd"])
        log = os.open(request["stderr"], os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
        os.dup2(log, 1)
        os.dup2(log, 2)
        os.close(log)
        with open("/proc/self/clear_refs", "w") as refs:   # resets VmHWM to the current RSS
            refs.write("5")
        reply = {"exception": None, "message": "", "defect": None}
        namespace = {"aos": aos, "np": np}
        try:
            exec(request["code"], namespace)
            reply["defect"] = non_finite(namespace.get("result"))
        except BaseException as error:   # everything: the class depends on the type
            reply["exception"] = type(error).__name__
            reply["message"] = str(error)
            traceback.print_exc()
        namespace.clear()
        sys.stdout.flush()
        sys.stderr.flush()
        os.dup2(saved_stderr, 1)
        os.dup2(saved_stderr, 2)
        reply["peak_rss_kb"] = peak_rss_kb()
        protocol.write(json.dumps(reply) + "\n")
        protocol.flush()


# =============================================================================================
# The viewer: one `aos-render view` server per job thread, and its HTTP and WebSocket clients.

TOKEN_HEADER = "X-AOS-Token"   # the viewer's session-token header (python/aos/viewer/server.py)
VIEWER_SENTINEL = b'{"type": "aos-fuzz-sentinel", "id": "aos-fuzz-sentinel"}'
VIEWER_LOG_FAILURES = re.compile(r"Traceback \(most recent call last\)|Error handling request")
# Header mutations of viewer cases (drawn in make_case, 10 % of the cases): the Host header
# (HTTP) or the Origin header (WebSocket) replaced.
VIEWER_HOSTS = ("evil.example", "", "127.0.0.1:0", "[::1", "localhost:99999", "a" * 300,
                "127.0.0.1:80:80", "\u00e9.example")
VIEWER_ORIGINS = ("http://evil.example", "null", "", "http://127.0.0.1", "file://")


class ViewerServer:
    """`aos-render view` on 127.0.0.1, any free port, over the corpus's simulated light field
    with the terrain mesh as focal surface, started in a folder of its own. Its stdout's first
    line (--json) gives the URL with the session's token; its stderr goes to a log that every
    case reads from where the previous one stopped (a traceback there is a failure)."""

    def __init__(self, fuzzer: "Fuzzer", folder: Path):
        self.fuzzer, self.folder = fuzzer, folder
        self.process: Optional[subprocess.Popen] = None
        self.port, self.token = 0, ""
        self.log = folder / "server.log"
        self.log_offset = 0

    def argv(self) -> list[str]:
        return [self.fuzzer.aos_render, "view", "in/sim/lightfield.json", *VIRTUAL_CAMERA[4:],
                "--focal-surface", "in/surface/terrain.obj", "--port", "0", "--no-browser",
                "--json"]

    def start(self) -> None:
        if not (self.folder / "in").exists():
            self.folder.mkdir(parents=True, exist_ok=True)
            shutil.copytree(self.fuzzer.corpus, self.folder / "in", symlinks=True)
        with open(self.log, "ab") as log:
            self.process = subprocess.Popen(
                self.argv(), cwd=self.folder, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                stderr=log, env=self.fuzzer.env, start_new_session=True,
                preexec_fn=limit_address_space(self.fuzzer.limits.address_space_mb))
        assert self.process.stdout
        ready, _, _ = select.select([self.process.stdout], [], [], 120.0)
        line = self.process.stdout.readline().decode() if ready else ""
        try:
            url = json.loads(line)["url"]
            self.port = int(json.loads(line)["port"])
            self.token = re.search(r"token=([A-Za-z0-9_-]+)", url).group(1)
        except (ValueError, KeyError, AttributeError, TypeError):
            tail = self.log.read_bytes()[-2000:].decode("utf-8", "replace")
            self.stop()
            raise RuntimeError(f"the viewer did not start: {line!r} {tail}")
        self.log_offset = self.log.stat().st_size

    def running(self) -> bool:
        return self.process is not None and self.process.poll() is None

    def stop(self) -> tuple[Optional[int], bool]:
        """SIGTERM, then SIGKILL after the grace time; (the signal that ended it or None,
        whether SIGKILL was needed)."""
        if not self.process:
            return None, False
        ignored = False
        if self.process.poll() is None:
            status, _, ignored = terminate(self.process.pid, self.fuzzer.limits.term_grace_s)
            self.process.returncode = os.waitstatus_to_exitcode(status)
        else:   # reaped by poll(): its group may still hold children
            try:
                os.killpg(self.process.pid, signal.SIGKILL)
            except (ProcessLookupError, PermissionError):
                pass
        code = self.process.returncode
        if self.process.stdout:
            self.process.stdout.close()
        self.process = None
        return (-code if code < 0 else None), ignored

    def new_log(self) -> str:
        data = self.log.read_bytes()
        text = data[self.log_offset:].decode("utf-8", "replace")
        self.log_offset = len(data)
        return text

    def peak_rss_kb(self) -> int:
        try:
            with open(f"/proc/{self.process.pid}/status") as status:
                return next(int(line.split()[1]) for line in status if line.startswith("VmHWM"))
        except (OSError, StopIteration, AttributeError):
            return 0


@dataclasses.dataclass
class ViewerAnswer:
    """What one viewer request got back."""
    kind: str = ""             # "http", "ws", or "none" (no answer in time / connection lost)
    status: int = 0            # HTTP status (the WebSocket handshake's for a refused upgrade)
    body: bytes = b""          # HTTP body, or the final WebSocket answer (text or binary)
    binary: bool = False       # WebSocket: the final answer was a binary frame
    close_code: Optional[int] = None   # WebSocket: the server closed with this code
    error: str = ""            # what went wrong on the client side (timeout, reset, ...)


def viewer_http(port: int, token: str, method: str, path: str, body: bytes,
                headers: dict[str, str], timeout: float) -> ViewerAnswer:
    connection = http.client.HTTPConnection("127.0.0.1", port, timeout=timeout)
    try:
        target = path
        if method == "GET":   # the document's items as the query string
            try:
                document = json.loads(body)
                items = document.items() if isinstance(document, dict) else [("q", body)]
            except (ValueError, UnicodeDecodeError, RecursionError):
                items = [("q", body)]
            query = urllib.parse.urlencode(
                [(str(k), v if isinstance(v, (str, bytes)) else json.dumps(v))
                 for k, v in items])
            target += "?" + query
            body = b""
        connection.putrequest(method, target, skip_host="Host" in headers,
                              skip_accept_encoding=True)
        for name, value in {TOKEN_HEADER: token, **headers}.items():
            connection.putheader(name, value.encode("utf-8", "surrogateescape"))
        if method == "POST":
            connection.putheader("Content-Type", "application/json")
            connection.putheader("Content-Length", str(len(body)))
        connection.endheaders(body if method == "POST" else None)
        response = connection.getresponse()
        return ViewerAnswer("http", response.status, response.read(1 << 24))
    except (socket.timeout, TimeoutError):
        return ViewerAnswer("none", error=f"no answer within {timeout:g} s")
    except (OSError, http.client.HTTPException) as error:
        return ViewerAnswer("none", error=f"{type(error).__name__}: {error}")
    finally:
        connection.close()


def ws_frame(opcode: int, payload: bytes) -> bytes:
    """A masked client frame (RFC 6455 section 5.2)."""
    mask = os.urandom(4)
    size = len(payload)
    head = bytes([0x80 | opcode])
    if size < 126:
        head += bytes([0x80 | size])
    elif size < 1 << 16:
        head += bytes([0x80 | 126]) + struct.pack(">H", size)
    else:
        head += bytes([0x80 | 127]) + struct.pack(">Q", size)
    return head + mask + bytes(b ^ mask[i % 4] for i, b in enumerate(payload))


def ws_read_frame(sock, deadline: float) -> tuple[int, bytes]:
    """(opcode, payload) of the server's next frame (fragments joined)."""
    def exactly(n: int) -> bytes:
        data = b""
        while len(data) < n:
            sock.settimeout(max(deadline - time.monotonic(), 0.001))
            chunk = sock.recv(n - len(data))
            if not chunk:
                raise ConnectionError("the server closed the connection")
            data += chunk
        return data
    payload, first_opcode = b"", None
    while True:
        b0, b1 = exactly(2)
        size = b1 & 0x7F
        if size == 126:
            (size,) = struct.unpack(">H", exactly(2))
        elif size == 127:
            (size,) = struct.unpack(">Q", exactly(8))
        if size > 1 << 26:
            raise ConnectionError(f"a frame of {size} bytes")
        mask = exactly(4) if b1 & 0x80 else b""
        data = exactly(size)
        if mask:
            data = bytes(b ^ mask[i % 4] for i, b in enumerate(data))
        opcode = b0 & 0x0F
        if opcode >= 8:                 # control frames come whole, between fragments too
            return opcode, data
        first_opcode = first_opcode if opcode == 0 else opcode
        payload += data
        if b0 & 0x80:
            return first_opcode or 1, payload


def viewer_ws(port: int, token: str, message: bytes, headers: dict[str, str],
              timeout: float) -> ViewerAnswer:
    """Sends `message` as a text frame, then a sentinel message the server answers at once
    with an error; reads until the answer to `message` (an error, a frame, a download, a
    cancellation: anything but progress and the sentinel's reply) has come, or, for a message
    that asks for no answer ("cancel"), the sentinel's reply."""
    deadline = time.monotonic() + timeout
    try:
        sock = socket.create_connection(("127.0.0.1", port), timeout=timeout)
    except OSError as error:
        return ViewerAnswer("none", error=f"connect: {error}")
    try:
        key = base64.b64encode(os.urandom(16)).decode()
        lines = [f"GET /ws?token={token} HTTP/1.1", f"Host: 127.0.0.1:{port}",
                 "Upgrade: websocket", "Connection: Upgrade", f"Sec-WebSocket-Key: {key}",
                 "Sec-WebSocket-Version: 13"]
        lines += [f"{name}: {value}" for name, value in headers.items()]
        sock.sendall(("\r\n".join(lines) + "\r\n\r\n").encode("utf-8", "surrogateescape"))
        response = b""
        while b"\r\n\r\n" not in response:
            sock.settimeout(max(deadline - time.monotonic(), 0.001))
            chunk = sock.recv(4096)
            if not chunk:
                raise ConnectionError("closed during the handshake")
            response += chunk
        head, _, rest = response.partition(b"\r\n\r\n")
        status = int(head.split(b" ", 2)[1])
        if status != 101:
            return ViewerAnswer("http", status, rest)
        sock.sendall(ws_frame(1, message) + ws_frame(1, VIEWER_SENTINEL))
        try:
            parsed = json.loads(message)
            silent = isinstance(parsed, dict) and parsed.get("type") == "cancel"
        except (ValueError, UnicodeDecodeError, RecursionError):
            silent = False
        sentinel_seen = False
        while True:
            opcode, payload = ws_read_frame(sock, deadline)
            if opcode == 8:
                code = struct.unpack(">H", payload[:2])[0] if len(payload) >= 2 else None
                return ViewerAnswer("ws", 101, payload[2:], close_code=code)
            if opcode in (9, 10):
                continue
            if opcode == 2:
                return ViewerAnswer("ws", 101, payload, binary=True)
            try:
                reply = json.loads(payload)
            except ValueError:
                return ViewerAnswer("ws", 101, payload)   # not JSON: checked as an answer
            if isinstance(reply, dict) and reply.get("id") == "aos-fuzz-sentinel":
                sentinel_seen = True
                if silent:
                    return ViewerAnswer("ws", 101, b"")
                continue
            if isinstance(reply, dict) and reply.get("type") == "progress":
                continue
            return ViewerAnswer("ws", 101, payload)
    except (socket.timeout, TimeoutError):
        return ViewerAnswer("none", error=f"no answer within {timeout:g} s")
    except (OSError, ConnectionError, ValueError, IndexError, struct.error) as error:
        return ViewerAnswer("none", error=f"{type(error).__name__}: {error}")
    finally:
        sock.close()


def viewer_frame_defect(data: bytes) -> Optional[str]:
    """A binary frame: uint32 header length, a JSON header with width and height, then
    width * height RGBA bytes."""
    if len(data) < 4:
        return f"a frame of {len(data)} bytes"
    (size,) = struct.unpack("<I", data[:4])
    try:
        header = strict_json(data[4:4 + size])
        width, height = int(header["width"]), int(header["height"])
    except (ValueError, KeyError, TypeError, UnicodeDecodeError) as error:
        return f"the frame header is not JSON with a width and height ({error})"
    if len(data) != 4 + size + 4 * width * height:
        return (f"the frame holds {len(data) - 4 - size} bytes of RGBA for {width} x {height} "
                "pixels")
    return None


def classify_viewer(case: "Case", answer: ViewerAnswer, log: str, server_exit: Optional[str],
                    limits: Limits, peak_rss_kb: int) -> tuple[str, str]:
    """The class of a viewer case (see the module docstring): the server's death or log first,
    then the answer."""
    log_lines = [line for line in log.splitlines() if line.strip()]
    if server_exit is not None:
        return "signal", f"the viewer server ended: {server_exit}; " + " | ".join(log_lines[-2:])
    if VIEWER_LOG_FAILURES.search(log):
        return "traceback", "server log: " + " | ".join(log_lines[-2:])[:300]
    if peak_rss_kb > limits.rss_mb * 1024:
        return "memory", f"viewer peak RSS {peak_rss_kb // 1024} MiB > {limits.rss_mb} MiB"
    if answer.kind == "none":
        return "timeout", answer.error
    text = answer.body[:300].decode("utf-8", "replace")
    if answer.kind == "http" or (answer.kind == "ws" and answer.status != 101):
        if answer.status >= 500:
            return "server-error", f"HTTP {answer.status}: {text}"
        if answer.status >= 400:
            return "refused", f"HTTP {answer.status}: {text}"
        if answer.status >= 300 or answer.kind == "ws":
            return "server-error", f"unexpected HTTP {answer.status}: {text}"
        path = VIEWER_ENDPOINTS.get(Path(case.file).name, ("", ""))[1]
        if path == "/api/render":
            defect = viewer_frame_defect(answer.body)
        elif path in ("/api/pick", "/api/command"):
            try:
                strict_json(answer.body)
                defect = None
            except (ValueError, UnicodeDecodeError) as error:
                defect = f"the answer is not finite JSON ({error})"
        else:
            defect = None if answer.body else "an empty export"
        return ("accepted-invalid", f"HTTP {answer.status}: {defect}") if defect else ("ok", "")
    if answer.close_code is not None:   # refusals by the WebSocket layer: too big, not UTF-8
        if answer.close_code in (1003, 1007, 1009):
            return "refused", f"closed with {answer.close_code} {text}"
        return "server-error", f"WebSocket closed with {answer.close_code} {text}"
    if answer.binary:
        defect = viewer_frame_defect(answer.body)
        return ("accepted-invalid", defect) if defect else ("ok", "")
    if not answer.body:
        return "ok", ""
    try:
        reply = strict_json(answer.body)
    except (ValueError, UnicodeDecodeError) as error:
        return "accepted-invalid", f"a WebSocket answer that is not finite JSON ({error})"
    kind = reply.get("type") if isinstance(reply, dict) else None
    if kind == "error":
        message = str(reply.get("message", ""))
        if re.match(r"(RuntimeError|TypeError|KeyError|AttributeError|IndexError|"
                    r"OverflowError|ZeroDivisionError|MemoryError|RecursionError)\b", message):
            return "server-error", f"WebSocket error from an uncaught exception: {message[:200]}"
        return "refused", message[:300]
    if kind in ("download", "cancelled"):
        return "ok", ""
    return "accepted-invalid", f"an unexpected WebSocket answer: {text}"


# =============================================================================================
# Cases and their classification.

SPECIAL_KINDS = ("fifo", "devzero", "folder", "output-is-input")
# Hand-made cases: in rounds 1 to 4 over the targets (cases n .. 5n - 1 for n targets) every
# target gets one file of its own replaced by each special kind (output-is-input: its output path
# set to that file, for targets with one output file); later rounds draw one 2 % of the time.
SPECIAL_ROUNDS = {1: "fifo", 2: "devzero", 3: "folder", 4: "output-is-input"}
SPECIAL_RATE = 0.02


@dataclasses.dataclass
class Case:
    index: int
    target: Target
    file: str                    # corpus-relative path of the mutated input
    kind: str = "bytes"          # "bytes" or one of SPECIAL_KINDS
    data: Optional[bytes] = None
    mutation: str = ""
    headers: dict = dataclasses.field(default_factory=dict)   # viewer: HTTP headers replaced


@dataclasses.dataclass
class Outcome:
    case: Case
    cls: str
    detail: str
    execution: Execution
    command: str


def file_state(root: Path) -> dict[str, tuple]:
    """Every entry below root (hidden ones too): (kind, size, mtime, sha1) for regular files,
    (kind,) for the rest; special files are never opened."""
    state = {}
    for dirpath, dirnames, filenames in os.walk(root):
        for name in dirnames + filenames:
            path = os.path.join(dirpath, name)
            info = os.lstat(path)
            key = os.path.relpath(path, root)
            if stat.S_ISREG(info.st_mode):
                with open(path, "rb") as f:
                    digest = hashlib.sha1(f.read()).hexdigest()
                state[key] = ("file", info.st_size, info.st_mtime_ns, digest)
            else:
                state[key] = (stat.S_IFMT(info.st_mode),)
    return state


MEMORY_WORDS = re.compile(r"bad_alloc|MemoryError|Cannot allocate memory|out of memory|"
                          r"Thread creation failed", re.I)


def error_shape(lines: list[str], name: str) -> tuple[str, str]:
    """(class, detail) of a refusal's message lines: exactly one line containing 'error', the
    last one, naming the file."""
    errors = [line for line in lines if "error" in line.lower()]
    if not errors:
        return "unnamed-error", "no error line: " + " | ".join(lines[-2:])
    if len(errors) > 1 or lines[-1] != errors[0]:
        return "multi-line-error", " | ".join(lines[lines.index(errors[0]):][:4])
    if not any(word in errors[0] for word in name.split("|")):
        return "unnamed-error", errors[0]
    return "refused", errors[0]


def classify(case: Case, execution: Execution, before: dict, after: dict, outputs: dict,
             case_dir: Path, limits: Limits) -> tuple[str, str]:
    """The class of a run and a one-line detail (see the module docstring)."""
    name = case.target.error_name or Path(case.file).name
    stderr_lines = [line for line in execution.stderr.splitlines() if line.strip()]
    failed = execution.returncode != 0
    if execution.ignored_sigterm:
        return "ignores-sigterm", (f"still running {limits.term_grace_s:g} s after SIGTERM "
                                   f"(sent after {limits.timeout_s:g} s); killed")
    if execution.timed_out:
        return "timeout", f"stopped by SIGTERM after {limits.timeout_s:g} s"
    python_memory = execution.exception_type == "MemoryError"
    last_lines = " | ".join(stderr_lines[-2:])
    if execution.signal is not None:
        if execution.signal == signal.SIGKILL or MEMORY_WORDS.search(execution.stderr):
            return "memory", f"killed by signal {execution.signal}; {last_lines}"
        return "signal", f"signal {signal.Signals(execution.signal).name}; {last_lines}"
    messages = execution.stderr + execution.exception_message
    if python_memory or (failed and MEMORY_WORDS.search(messages)):
        return "memory", (execution.exception_message or " | ".join(stderr_lines[-2:]))[:300]
    if execution.peak_rss_kb > limits.rss_mb * 1024:
        return "memory", f"peak RSS {execution.peak_rss_kb // 1024} MiB > {limits.rss_mb} MiB"
    changed = sorted(k for k in before if after.get(k) != before[k])
    if changed:
        return "modified-input", "changed or removed: " + ", ".join(changed[:5])
    new_inputs = sorted(set(after) - set(before))
    if failed and (outputs or new_inputs):
        return "partial-output", "left behind: " + ", ".join((sorted(outputs) + new_inputs)[:5])
    if new_inputs:
        return "modified-input", "new files among the inputs: " + ", ".join(new_inputs[:5])
    if case.target.kind == "cli":
        if "Traceback (most recent call last)" in execution.stderr:
            return "traceback", " | ".join(stderr_lines[-2:])
        if failed:
            return error_shape(stderr_lines, name)
    elif execution.exception_type is not None:
        message = execution.exception_message
        if execution.exception_type != "ValueError":
            return "traceback", f"{execution.exception_type}: {message}"[:300]
        lines = [line for line in message.splitlines() if line.strip()] or [""]
        if len(lines) > 1:
            return "multi-line-error", " | ".join(lines[:4])
        if name not in message:
            return "unnamed-error", message
        return "refused", message
    elif failed:   # the worker exited without answering and without a signal
        return "signal", "the Python worker exited: " + " | ".join(stderr_lines[-2:])
    return accepted_class(case, execution, case_dir)


def gdal_holes(case: Case, path: Path, defect: str) -> bool:
    """A DEM (read by GDAL) that declares a nodata value (TIFF tag 42113) reads the blocks its
    file lacks as nodata: holes, which aos accepts (heightfield.cpp refuses the file only when
    it declares none, where GDAL would read heights of 0)."""
    if "dem" not in case.target.name or not re.match(r"(declares|\d+ rows need|strip)", defect):
        return False
    try:
        return 42113 in Tiff(path.read_bytes()).tags
    except (ValueError, struct.error, OSError):
        return False


def accepted_class(case: Case, execution: Execution, case_dir: Path) -> tuple[str, str]:
    """ok, or accepted-invalid with the defect found in the input or the outputs."""
    if case.kind == "bytes" and case.target.decodes_pixels:
        defect = image_defect(case_dir / "in" / case.file)
        if defect and gdal_holes(case, case_dir / "in" / case.file, defect):
            defect = None
        if defect:
            return "accepted-invalid", f"accepted {case.file}: {defect}"
    if case.kind == "bytes" and case.file.startswith("exif/"):   # frames read for their tags
        defect = gps_defect(case.data or b"")
        if defect:
            return "accepted-invalid", f"accepted {case.file}: {defect}"
    if execution.result_defect:
        return "accepted-invalid", "the result holds " + execution.result_defect
    for promised in case.target.outputs:
        path = case_dir / case.target.format(promised, case.file, "")
        if not path.exists():
            return "accepted-invalid", f"exit 0 without {promised}"
    for path in sorted((case_dir / "out").rglob("*")):
        if path.is_file():
            defect = output_defect(path)
            if defect:
                return "accepted-invalid", f"output {path.relative_to(case_dir)}: {defect}"
    if case.target.stdout_json:
        try:
            strict_json(execution.stdout)
        except ValueError as error:
            return "accepted-invalid", f"stdout is not finite JSON ({error})"
    return "ok", ""


# =============================================================================================
# The fuzzer: corpus, cases, minimisation, reproducers.

class Fuzzer:
    def __init__(self, aos_render: str, python_path: Optional[str], limits: Limits,
                 work: Path, corpus: Optional[Path] = None):
        self.aos_render, self.python_path, self.limits = aos_render, python_path, limits
        self.work = work
        self.corpus = corpus or work / "corpus"
        self.env = child_environment(python_path)
        self.local = threading.local()
        self.workers: list[PythonWorker] = []
        self.viewers: list[ViewerServer] = []
        self.lock = threading.Lock()
        self.counter = 0
        self.splice_sources: Optional[list[tuple[str, bytes]]] = None

    # --- execution of one case --------------------------------------------------------------

    def worker(self) -> PythonWorker:
        if not hasattr(self.local, "worker"):
            self.local.worker = PythonWorker(self.python_path, self.limits)
            with self.lock:
                self.workers.append(self.local.worker)
        return self.local.worker

    def close(self) -> None:
        for worker in self.workers:
            worker.stop()
        for viewer in self.viewers:
            viewer.stop()

    def command(self, case: Case) -> tuple[list[str], str]:
        """(argv, Python code) of the case; paths relative to the case folder. {text}: the
        mutated file's bytes as one argument (NUL bytes dropped: argv cannot hold them; other
        bytes kept, invalid UTF-8 included, through surrogateescape)."""
        target, file = case.target, "in/" + case.file
        text = ""
        if target.text_argument:
            data = case.data if case.kind == "bytes" else (self.corpus / case.file).read_bytes()
            # At most 100 kB: Linux refuses a single argument of 128 kB (MAX_ARG_STRLEN).
            text = os.fsdecode((data or b"").replace(b"\0", b"")[:100000])
        argv = [target.format(a, file, self.aos_render, text) for a in target.argv]
        code = target.format(target.code, file, self.aos_render) if target.code else ""
        if case.kind == "output-is-input" and target.output_file:
            argv = [file if a == target.output_file else a for a in argv]
        return argv, code

    def describe(self, case: Case) -> str:
        if case.target.kind == "viewer":
            method, path = VIEWER_ENDPOINTS.get(Path(case.file).name, ("WebSocket message to",
                                                                       "/ws"))
            headers = "".join(f" with {k}: {v[:40]!r}" for k, v in case.headers.items())
            server = ViewerServer(self, Path("."))
            return (f"{method} {path} ({len(case.data or b'')} bytes of {case.file}){headers} "
                    f"to: cd <corpus>/.. && {shlex.join(server.argv())}")
        argv, code = self.command(case)
        if code:
            env = f"env PYTHONPATH={shlex.quote(self.python_path)} " if self.python_path else ""
            code = "import aos; " + code
            # Double quotes read better around Python's single-quoted strings, where they are safe.
            quoted = f'"{code}"' if not re.search(r'["$`\\!]', code) else shlex.quote(code)
            return f"{env}{shlex.quote(sys.executable)} -c {quoted}"
        return shlex.join(argv)

    def prepare(self, case: Case, case_dir: Path) -> None:
        shutil.copytree(self.corpus, case_dir / "in", symlinks=True)
        (case_dir / "out").mkdir()
        path = case_dir / "in" / case.file
        if case.kind == "bytes":
            path.write_bytes(case.data or b"")
        elif case.kind in ("fifo", "devzero", "folder"):
            path.unlink()
            {"fifo": os.mkfifo, "folder": os.mkdir,
             "devzero": lambda p: os.symlink("/dev/zero", p)}[case.kind](path)

    def viewer(self) -> ViewerServer:
        if not hasattr(self.local, "viewer"):
            with self.lock:
                self.counter += 1
                folder = self.work / f"viewer-{self.counter}"
            self.local.viewer = ViewerServer(self, folder)
            with self.lock:
                self.viewers.append(self.local.viewer)
        return self.local.viewer

    def execute_viewer(self, case: Case) -> Outcome:
        """One request to this thread's viewer server (started on first use, and again after
        it died or hung): the class from its answer, its log and whether it survived."""
        server = self.viewer()
        if not server.running():
            try:
                server.start()
            except RuntimeError as error:
                if case.index < 0:   # the unmutated corpus: the set-up failed
                    raise
                return Outcome(case, "signal", f"the viewer server did not start again: {error}",
                               Execution(), self.describe(case))
        server.new_log()
        method, path = VIEWER_ENDPOINTS.get(Path(case.file).name, ("WS", "/ws"))
        data = case.data or b""
        start = time.monotonic()
        if method == "WS":
            answer = viewer_ws(server.port, server.token, data, case.headers, self.limits.timeout_s)
        else:
            answer = viewer_http(server.port, server.token, method, path, data, case.headers,
                                 self.limits.timeout_s)
        execution = Execution(wall_s=time.monotonic() - start, returncode=0)
        time.sleep(0.05)   # lets the server finish writing its log for this request
        server_exit = None
        if not server.running():
            code = server.process.returncode if server.process else None
            server_exit = (f"signal {signal.Signals(-code).name}" if code is not None and code < 0
                           else f"exit status {code}")
            server.stop()
        peak = server.peak_rss_kb() if server.running() else 0
        log = server.new_log()
        cls, detail = classify_viewer(case, answer, log, server_exit, self.limits, peak)
        if cls in ("timeout", "memory") and server.running():   # a hung or bloated server
            _, ignored = server.stop()
            if ignored:
                cls, detail = "ignores-sigterm", (f"the viewer server was still running "
                                                  f"{self.limits.term_grace_s:g} s after "
                                                  f"SIGTERM; {detail}")
        execution.stderr = log
        execution.stdout = answer.body[:2000].decode("utf-8", "replace")
        execution.peak_rss_kb = peak
        return Outcome(case, cls, detail, execution, self.describe(case))

    def execute(self, case: Case) -> Outcome:
        if case.target.kind == "viewer":
            return self.execute_viewer(case)
        with self.lock:
            self.counter += 1
            case_dir = self.work / f"case-{case.index}-{self.counter}"
        log_dir = case_dir.with_name(case_dir.name + ".log")
        case_dir.mkdir()
        log_dir.mkdir()
        try:
            self.prepare(case, case_dir)
            before = {k: v for k, v in file_state(case_dir).items() if not k.startswith("out")}
            argv, code = self.command(case)
            if code:
                execution = self.worker().run(code, case_dir, log_dir)
            else:
                execution = run_process(argv, case_dir, self.limits, self.env, log_dir)
            state = file_state(case_dir)
            after = {k: v for k, v in state.items() if not k.startswith("out")}
            outputs = {k: v for k, v in state.items() if k.startswith("out" + os.sep)}
            cls, detail = classify(case, execution, before, after, outputs, case_dir, self.limits)
            return Outcome(case, cls, detail, execution, self.describe(case))
        finally:
            shutil.rmtree(case_dir, ignore_errors=True)
            shutil.rmtree(log_dir, ignore_errors=True)

    # --- the corpus -------------------------------------------------------------------------

    def build_corpus(self) -> None:
        """The seed corpus (see the module docstring), made with the build under test."""
        root = self.corpus
        root.mkdir(parents=True)
        (root / "scene.json").write_text(json.dumps(TINY_SCENE, indent=2) + "\n")
        self.run_cli(["simulate", "scene.json", "-o", "sim", "-q"], root)
        for extra in ("truth", "scene.json", "lightfield_true.json"):
            path = root / "sim" / extra
            shutil.rmtree(path) if path.is_dir() else path.unlink(missing_ok=True)
        self.run_cli(["stack", "sim/lightfield.json", *VIRTUAL_CAMERA, "--slices", "2",
                      "--first-plane", "0", "--last-plane", "4", "-o", "stack", "-q"], root)
        light_field = json.loads((root / "sim/lightfield.json").read_text())
        views = [(Path(v["image"]).name, v["cam_from_world"]) for v in light_field["views"]]
        camera = next(iter(light_field["cameras"].values()))
        write_jku(root / "jku", root / "sim", views)
        write_colmap_text(root / "colmap_txt", camera, views)
        write_colmap_binary(root / "colmap_bin", camera, views)
        write_positions(root / "positions.csv", views)
        (root / "camera.json").write_text(json.dumps(CAMERA_FILE, indent=2) + "\n")
        self.write_images(root / "images")
        shutil.copytree(root / "images", root / "ref")
        write_viewer_requests(root / "viewer")
        write_telemetry(root / "telemetry", views)
        write_meshes(root / "surface")
        (root / "plan").mkdir()
        write_plan_vertices(root / "plan" / "polygon.vertices")
        self.write_rasters(root, [name for name, _ in views])
        for i, jpeg in enumerate(sorted((root / "exif").glob("*.jpg"))):
            jpeg.write_bytes(with_app_segments(
                jpeg.read_bytes(), exif_gps_segment(48 + 1e-5 * i, 15.0 + 1e-5 * i, 400.0 + i)
                + xmp_dji_segment(12.3 + i, -90.0, 0.0, 20.0 + 0.1 * i)))

    def run_cli(self, args: list[str], cwd: Path) -> None:
        result = subprocess.run([self.aos_render, *args], cwd=cwd, env=self.env,
                                capture_output=True, text=True, timeout=300)
        if result.returncode != 0:
            raise RuntimeError(f"corpus: aos-render {' '.join(args)} failed: {result.stderr}")

    def write_images(self, folder: Path) -> None:
        """One 32 x 32 image of every format (aos.write_image in the worker), plus an
        uncompressed float TIFF written here (its samples can be set to NaN by the mutations)."""
        folder.mkdir()
        code = (
            "v = (np.arange(32)[:, None] * 7 + np.arange(32)[None, :] * 3) % 256\n"
            "g8 = v.astype(np.uint8)\n"
            "rgb = np.stack([g8, 255 - g8, g8 // 2], axis=-1)\n"
            "for name, array in [('gray8.png', g8), ('gray16.png', g8.astype(np.uint16) * 257),\n"
            "                    ('rgb8.png', rgb), ('gray8.tif', g8),\n"
            "                    ('gray16.tif', g8.astype(np.uint16) * 257),\n"
            "                    ('float.tif', (g8 / 255).astype(np.float32)),\n"
            "                    ('float.exr', (g8 / 255).astype(np.float32)),\n"
            "                    ('gray8.jpg', g8), ('rgb8.jpg', rgb)]:\n"
            f"    aos.write_image({str(folder)!r} + '/' + name, array)\n")
        log = self.work / "corpus-images.log"
        log.mkdir(exist_ok=True)
        execution = self.worker().run(code, self.work, log)
        if execution.returncode != 0:
            raise RuntimeError(f"corpus: writing the images failed: {execution.stderr}")
        import numpy as np
        v = (np.arange(IMAGE_SIZE)[:, None] * 7 + np.arange(IMAGE_SIZE)[None, :] * 3) % 256
        pixels = (v / 255).astype("<f4").tobytes()
        (folder / "float-raw.tif").write_bytes(tiff_file(IMAGE_SIZE, IMAGE_SIZE, pixels, 32, 3))
        shutil.rmtree(log)

    def write_rasters(self, root: Path, view_names: list[str]) -> None:
        """In the worker, with aos's writers: the DEMs (float32 GeoTIFFs: surface/dem.tif in the
        simulated light field's frame without a CRS, plan/dem.tif in UTM zone 33 under the plan
        polygon), the masks (mask.png for every view, masks/<view name> one per view: a disc of
        valid pixels, a different radius per view) and the frames of the EXIF target
        (exif/frame_N.jpg, tagged afterwards)."""
        code = (
            "import os\n"
            "v = np.add.outer(np.arange(8.0), np.arange(8.0)).astype(np.float32)\n"
            "aos.Heightfield(0.1 * v, (-20.0, 5.0, 0.0, 20.0, 0.0, -5.0)).write("
            "'surface/dem.tif')\n"
            "aos.Heightfield(300 + v, (499990.0, 10.0, 0.0, 5300060.0, 0.0, -10.0), "
            "'EPSG:32633').write('plan/dem.tif')\n"
            f"n = {IMAGE_SIZE}\n"
            "yy, xx = np.mgrid[0:n, 0:n]\n"
            "r2 = (xx - n / 2 + 0.5) ** 2 + (yy - n / 2 + 0.5) ** 2\n"
            "aos.write_image('mask.png', (r2 < (0.45 * n) ** 2).astype(np.uint8) * 255)\n"
            "os.mkdir('masks')\n"
            f"for i, name in enumerate({view_names!r}):\n"
            "    radius = (0.3 + 0.02 * i) * n\n"
            "    aos.write_image('masks/' + name, (r2 < radius ** 2).astype(np.uint8) * 255)\n"
            "os.mkdir('exif')\n"
            "g = ((xx * 7 + yy * 3) % 256).astype(np.uint8)\n"
            "for i in range(3):\n"
            "    aos.write_image(f'exif/frame_{i}.jpg', g)\n")
        log = self.work / "corpus-rasters.log"
        log.mkdir(exist_ok=True)
        execution = self.worker().run(code, root, log)
        if execution.returncode != 0:
            raise RuntimeError(f"corpus: writing the rasters failed: {execution.stderr}")
        shutil.rmtree(log)

    def check_corpus(self, targets: list[Target], jobs: int) -> list[Outcome]:
        """Every target on the unmutated corpus; a target whose command names the file ({file})
        once per file name pattern (digits ignored: views/0000.png stands for all views).
        Returns the runs that were not ok."""
        cases = []
        for target in targets:
            names_file = target.kind == "viewer" or any(
                "{file}" in a or "{name}" in a for a in target.argv + (target.code,))
            files = [f for pattern in target.files for f in self.files(pattern)]
            if names_file:
                files = list({re.sub(r"\d+", "N", f): f for f in files}.values())
            for file in files[:len(files) if names_file else 1]:
                cases.append(Case(-1, target, file, "bytes", (self.corpus / file).read_bytes(),
                                  "none (unmutated corpus)"))
        with concurrent.futures.ThreadPoolExecutor(max_workers=jobs) as pool:
            return [o for o in pool.map(self.execute, cases) if o.cls != "ok"]

    def files(self, pattern: str) -> list[str]:
        found = sorted(str(p.relative_to(self.corpus)) for p in self.corpus.glob(pattern)
                       if p.is_file())
        if not found:
            raise RuntimeError(f"corpus: no file matches {pattern}")
        return found

    # --- cases ------------------------------------------------------------------------------

    def make_case(self, seed: int, index: int, targets: list[Target]) -> Case:
        """Case `index` of `seed`: deterministic, independent of the other cases."""
        rng = random.Random(f"{seed}:{index}")
        target = targets[index % len(targets)]
        file = rng.choice(self.files(rng.choice(target.files)))
        special = SPECIAL_ROUNDS.get(index // len(targets))
        if special is None and rng.random() < SPECIAL_RATE:
            special = rng.choice(SPECIAL_KINDS)
        if ((special == "output-is-input" and not target.output_file) or target.text_argument
                or target.kind == "viewer"):
            special = None   # {text} and viewer targets: the fuzzer reads the file, not aos
        if special:
            description = {"fifo": "a FIFO", "devzero": "a symbolic link to /dev/zero",
                           "folder": "an empty folder",
                           "output-is-input": "the output path"}[special]
            return Case(index, target, file, special, None, f"{file} replaced by {description}"
                        if special != "output-is-input" else f"output path set to {file}")
        data = (self.corpus / file).read_bytes()
        if self.splice_sources is None:
            self.splice_sources = [(str(p.relative_to(self.corpus)), p.read_bytes())
                                   for p in sorted(self.corpus.rglob("*")) if p.is_file()]
        mutated, description = mutate(rng, data, MutationContext(file, self.splice_sources))
        headers: dict[str, str] = {}
        if target.kind == "viewer":
            roll = rng.random()
            if roll < 0.08:   # oversized: past the server's 64 KiB limit on bodies and messages
                mutated = data.rstrip()[:-1] + b', "padding": "' + b"x" * 70000 + b'"}'
                description = "a 70 kB request (past MAX_BODY_BYTES)"
            elif roll < 0.18:
                if file.startswith("viewer/ws_"):
                    headers["Origin"] = rng.choice(VIEWER_ORIGINS)
                else:
                    headers["Host"] = rng.choice(VIEWER_HOSTS)
                name, value = next(iter(headers.items()))
                description += f"; header {name}: {value[:40]!r}"
        return Case(index, target, file, "bytes", mutated, description, headers)

    def minimise(self, outcome: Outcome, budget_s: float) -> bytes:
        """Delta debugging: removes chunks (halves, quarters, ... down to single bytes) while
        the class stays the same, within budget_s seconds."""
        case = outcome.case
        data = case.data or b""
        deadline = time.monotonic() + budget_s
        parts = 2
        while len(data) > 1 and time.monotonic() < deadline:
            chunk = -(-len(data) // parts)
            for start in range(0, len(data), chunk):
                if time.monotonic() >= deadline:
                    break
                candidate = data[:start] + data[start + chunk:]
                probe = dataclasses.replace(case, data=candidate)
                if self.execute(probe).cls == outcome.cls:
                    data, parts = candidate, max(parts - 1, 2)
                    break
            else:
                if chunk == 1:
                    break
                parts = min(parts * 2, len(data))
        return data

    def save(self, outcome: Outcome, data: Optional[bytes], minimised: bool, seed: int,
             out: Path, replay: str) -> Path:
        """The reproducer: the (minimised) file, case.json and reproduce.sh."""
        case = outcome.case
        folder = out / f"{outcome.cls}-{case.target.name}-case{case.index}"
        folder.mkdir(parents=True, exist_ok=True)
        name = Path(case.file).name
        if data is not None:
            (folder / name).write_bytes(data)
            if minimised:
                (folder / ("original." + name)).write_bytes(case.data or b"")
        stderr_tail = outcome.execution.stderr[-2000:]
        record = {
            "target": case.target.name, "seed": seed, "case": case.index, "class": outcome.cls,
            "detail": outcome.detail, "file": case.file, "kind": case.kind,
            "mutation": case.mutation, "minimised": minimised, "command": outcome.command,
            "cwd": "a copy of the corpus in in/, an empty out/ (see reproduce.sh)",
            "returncode": outcome.execution.returncode, "signal": outcome.execution.signal,
            "peak_rss_mb": outcome.execution.peak_rss_kb // 1024,
            "wall_s": round(outcome.execution.wall_s, 3), "stderr_tail": stderr_tail,
            "replay": f"{replay} --case {case.index}",
        }
        (folder / "case.json").write_text(json.dumps(record, indent=2) + "\n")
        setup = {
            "bytes": f'cp "$here/{name}" "in/{case.file}"',
            "fifo": f'rm "in/{case.file}" && mkfifo "in/{case.file}"',
            "devzero": f'rm "in/{case.file}" && ln -s /dev/zero "in/{case.file}"',
            "folder": f'rm "in/{case.file}" && mkdir "in/{case.file}"',
            "output-is-input": ":",
        }[case.kind]
        if case.target.kind == "viewer":   # a request to a server: replayed by the fuzzer
            setup = ":"
            outcome = dataclasses.replace(outcome, command=(
                f"{replay} --case {case.index}".replace("tools/fuzz.py",
                                                        shlex.quote(os.path.abspath(__file__)))))
        script = (f"#!/bin/sh\n# {case.target.name}, case {case.index} of seed {seed}: "
                  f"{outcome.cls}\n# {outcome.detail}\nset -e\n"
                  "here=$(cd \"$(dirname \"$0\")\" && pwd)\n"
                  "work=$(mktemp -d)\ncp -r \"$here/../corpus\" \"$work/in\"\nmkdir \"$work/out\"\n"
                  f"cd \"$work\"\n{setup}\necho \"case folder: $work\" >&2\n"
                  f"exec {outcome.command}\n")
        # An argument from {text} may hold invalid UTF-8: written back as the bytes it was.
        (folder / "reproduce.sh").write_bytes(script.encode("utf-8", "surrogateescape"))
        (folder / "reproduce.sh").chmod(0o755)
        return folder


def write_jku(folder: Path, sim: Path, views) -> None:
    """JKU-ICG poses.json (M3x4 = cam_from_world as 3 rows of 4) with the frames in ../images."""
    (folder / "poses").mkdir(parents=True)
    shutil.copytree(sim / "views", folder / "images")
    images = [{"imagefile": name,
               "M3x4": [row + [t] for row, t in zip(pose["rotation"], pose["translation"])]}
              for name, pose in views]
    (folder / "poses" / "poses.json").write_text(json.dumps({"images": images}, indent=2) + "\n")


def colmap_quaternion(rotation) -> tuple[float, float, float, float]:
    """(w, x, y, z) of a rotation matrix (Shepperd's method, largest-diagonal branch)."""
    (r00, r01, r02), (r10, r11, r12), (r20, r21, r22) = rotation
    trace = r00 + r11 + r22
    if trace > 0:
        s = 2 * math.sqrt(1 + trace)
        return s / 4, (r21 - r12) / s, (r02 - r20) / s, (r10 - r01) / s
    if r00 >= r11 and r00 >= r22:
        s = 2 * math.sqrt(1 + r00 - r11 - r22)
        return (r21 - r12) / s, s / 4, (r01 + r10) / s, (r02 + r20) / s
    if r11 >= r22:
        s = 2 * math.sqrt(1 + r11 - r00 - r22)
        return (r02 - r20) / s, (r01 + r10) / s, s / 4, (r12 + r21) / s
    s = 2 * math.sqrt(1 + r22 - r00 - r11)
    return (r10 - r01) / s, (r02 + r20) / s, (r12 + r21) / s, s / 4


def write_colmap_text(folder: Path, camera: dict, views) -> None:
    folder.mkdir()
    (folder / "cameras.txt").write_text(
        "# Camera list with one line of data per camera:\n"
        f"1 PINHOLE {camera['width']} {camera['height']} {camera['fx']} {camera['fy']} "
        f"{camera['cx']} {camera['cy']}\n")
    lines = ["# Image list with two lines of data per image:"]
    for i, (name, pose) in enumerate(views, start=1):
        q, t = colmap_quaternion(pose["rotation"]), pose["translation"]
        lines += [f"{i} {' '.join(map(repr, q))} {' '.join(map(repr, t))} 1 {name}", ""]
    (folder / "images.txt").write_text("\n".join(lines) + "\n")
    (folder / "points3D.txt").write_text("# 3D point list with one line of data per point:\n")


def write_colmap_binary(folder: Path, camera: dict, views) -> None:
    folder.mkdir()
    (folder / "cameras.bin").write_bytes(struct.pack(
        "<QIiQQ4d", 1, 1, 1, camera["width"], camera["height"], camera["fx"], camera["fy"],
        camera["cx"], camera["cy"]))
    images = struct.pack("<Q", len(views))
    for i, (name, pose) in enumerate(views, start=1):
        images += struct.pack("<I7dI", i, *colmap_quaternion(pose["rotation"]),
                              *pose["translation"], 1)
        images += name.encode() + b"\0" + struct.pack("<Q", 0)
    (folder / "images.bin").write_bytes(images)
    (folder / "points3D.bin").write_bytes(struct.pack("<Q", 0))


def write_positions(path: Path, views) -> None:
    """Camera centres (-R^T t) moved to UTM-like coordinates, metres."""
    rows = ["name,x,y,z"]
    for name, pose in views:
        r, t = pose["rotation"], pose["translation"]
        centre = [-sum(r[k][j] * t[k] for k in range(3)) for j in range(3)]
        rows.append(f"{name},{500000 + centre[0]!r},{5300000 + centre[1]!r},{300 + centre[2]!r}")
    path.write_text("\n".join(rows) + "\n")


def write_telemetry(folder: Path, views) -> None:
    """Two flight logs of the simulated views (import-telemetry --telemetry-file): one row per
    frame by name, and one by time (1 s per frame, --frame-interval-s 1), nadir, heading north,
    on UTM zone 33's central meridian."""
    folder.mkdir()
    header = "lat,lon,alt,yaw,pitch,roll\n"
    by_name = "".join(f"{name},{48 + 1e-5 * i:.7f},15.0,{20 + 0.1 * i:.1f},0,-90,0\n"
                      for i, (name, _) in enumerate(views))
    (folder / "frames.csv").write_text("frame," + header + by_name)
    by_time = "".join(f"{i - 0.5:g},{48 + 1e-5 * i:.7f},15.0,20.0,{(359 + 2 * i) % 360},-90,0\n"
                      for i in range(len(views) + 1))
    (folder / "time.csv").write_text("# a log sampled between the frames\ntime," + header + by_time)


def exif_gps_segment(lat: float, lon: float, altitude: float) -> bytes:
    """A JPEG APP1 Exif segment holding only a GPS IFD (version, latitude/longitude as degrees,
    minutes, seconds rationals with their N/S, E/W references, altitude above sea level): the
    tags a drone writes and ReadGpsTag reads. Little-endian TIFF layout; the offsets are from the
    TIFF header."""
    def dms(value: float) -> list[tuple[int, int]]:
        value = abs(value)
        degrees = int(value)
        minutes = int((value - degrees) * 60)
        seconds = round((value - degrees - minutes / 60) * 3600 * 10000)
        return [(degrees, 1), (minutes, 1), (seconds, 10000)]
    rationals = {2: dms(lat), 4: dms(lon), 6: [(round(abs(altitude) * 1000), 1000)]}
    ascii_refs = {1: b"N\0" if lat >= 0 else b"S\0", 3: b"E\0" if lon >= 0 else b"W\0"}
    tags = [0, 1, 2, 3, 4, 5, 6]
    gps_ifd_at = 8 + 2 + 12 + 4                   # IFD0: one entry (the GPS IFD pointer)
    data_at = gps_ifd_at + 2 + 12 * len(tags) + 4
    entries, data = b"", b""
    for tag in tags:
        if tag == 0:
            entries += struct.pack("<HHI4s", 0, 1, 4, bytes([2, 3, 0, 0]))
        elif tag in ascii_refs:
            entries += struct.pack("<HHI4s", tag, 2, 2, ascii_refs[tag].ljust(4, b"\0"))
        elif tag == 5:
            entries += struct.pack("<HHI4s", 5, 1, 1, bytes([0 if altitude >= 0 else 1, 0, 0, 0]))
        else:
            values = rationals[tag]
            entries += struct.pack("<HHII", tag, 5, len(values), data_at + len(data))
            data += b"".join(struct.pack("<II", n, d) for n, d in values)
    tiff = (b"II*\0" + struct.pack("<I", 8) + struct.pack("<H", 1)
            + struct.pack("<HHII", 0x8825, 4, 1, gps_ifd_at) + struct.pack("<I", 0)
            + struct.pack("<H", len(tags)) + entries + struct.pack("<I", 0) + data)
    payload = b"Exif\0\0" + tiff
    return b"\xff\xe1" + struct.pack(">H", len(payload) + 2) + payload


def xmp_dji_segment(yaw: float, pitch: float, roll: float, relative_altitude: float) -> bytes:
    """A JPEG APP1 XMP segment with DJI's gimbal angles and relative altitude (drone-dji:...,
    attribute form with DJI's explicit signs)."""
    packet = ('<?xpacket begin="\ufeff" id="W5M0MpCehiHzreSzNTczkc9d"?>'
              '<x:xmpmeta xmlns:x="adobe:ns:meta/"><rdf:RDF '
              'xmlns:rdf="http://www.w3.org/1999/02/22-rdf-syntax-ns#"><rdf:Description '
              'rdf:about="" xmlns:drone-dji="http://www.dji.com/drone-dji/1.0/" '
              f'drone-dji:RelativeAltitude="{relative_altitude:+.2f}" '
              f'drone-dji:GimbalRollDegree="{roll:+.2f}" '
              f'drone-dji:GimbalYawDegree="{yaw:+.2f}" '
              f'drone-dji:GimbalPitchDegree="{pitch:+.2f}"/>'
              '</rdf:RDF></x:xmpmeta><?xpacket end="w"?>').encode()
    payload = b"http://ns.adobe.com/xap/1.0/\0" + packet
    return b"\xff\xe1" + struct.pack(">H", len(payload) + 2) + payload


def with_app_segments(jpeg: bytes, segments: bytes) -> bytes:
    """The JPEG with `segments` inserted after its SOI and JFIF APP0 (if any)."""
    at = 2
    if jpeg[2:4] == b"\xff\xe0":
        (length,) = struct.unpack(">H", jpeg[4:6])
        at = 4 + length
    return jpeg[:at] + segments + jpeg[at:]


def terrain_grid(n: int = 5, half: float = 20.0) -> tuple[list, list]:
    """An n x n vertex grid over [-half, half]^2 near z = 0 (the simulated ground) and its
    triangles (0-based): the focal surface of the surface targets."""
    step = 2 * half / (n - 1)
    vertices = [(-half + i * step, -half + j * step, 0.05 * ((i + j) % 3))
                for j in range(n) for i in range(n)]
    triangles = []
    for j in range(n - 1):
        for i in range(n - 1):
            a = j * n + i
            triangles += [(a, a + 1, a + n + 1), (a, a + n + 1, a + n)]
    return vertices, triangles


def write_meshes(folder: Path) -> None:
    """The terrain as OBJ (quads as two triangles, v/vt/vn corners, comments), ascii PLY (an
    extra colour property) and binary little-endian PLY (double coordinates, uchar/int lists)."""
    folder.mkdir()
    vertices, triangles = terrain_grid()
    obj = ["# aos fuzz terrain", "o ground"]
    obj += [f"v {x:g} {y:g} {z:g}" for x, y, z in vertices] + ["vt 0 0", "vn 0 0 1"]
    obj += [f"f {a + 1}/1/1 {b + 1}/1/1 {c + 1}//1" for a, b, c in triangles]
    (folder / "terrain.obj").write_text("\n".join(obj) + "\n")
    header = ("ply\nformat {}\ncomment aos fuzz terrain\nelement vertex {}\n"
              "property {t} x\nproperty {t} y\nproperty {t} z\n{extra}element face {}\n"
              "property list uchar int vertex_indices\nend_header\n")
    ascii_ply = header.format("ascii 1.0", len(vertices), len(triangles), t="float",
                              extra="property uchar red\n")
    ascii_ply += "".join(f"{x:g} {y:g} {z:g} {k % 256}\n" for k, (x, y, z) in enumerate(vertices))
    ascii_ply += "".join(f"3 {a} {b} {c}\n" for a, b, c in triangles)
    (folder / "terrain.ply").write_text(ascii_ply)
    binary = header.format("binary_little_endian 1.0", len(vertices), len(triangles),
                           t="double", extra="").encode()
    binary += b"".join(struct.pack("<3d", *v) for v in vertices)
    binary += b"".join(struct.pack("<B3i", 3, *t) for t in triangles)
    (folder / "terrain_binary.ply").write_bytes(binary)


def write_plan_vertices(path: Path) -> None:
    """The polygon of the plan targets (--vertices X,Y;X,Y;...): UTM zone 33 metres."""
    corners = [(500000, 5300000), (500060, 5300000), (500070, 5300030), (500030, 5300050),
               (500000, 5300040)]
    path.write_text(";".join(f"{x},{y}" for x, y in corners))   # no newline: one argument


# The viewer's requests (viewer/*.json): the HTTP ones by file name (VIEWER_ENDPOINTS), the
# WebSocket messages (ws_*.json) sent as text frames. GET endpoints take the object's items as
# the query string. Parameters: python/aos/viewer/session.py.
VIEWER_REQUESTS = {
    "render.json": {"mode": "perspective", "focal_height": 2.0, "aperture_radius": "inf",
                    "width": 32, "height": 32, "colormap": "turbo", "range": "auto",
                    "gain": 1.5, "offset": 0.1, "orbit_deg": 10, "tilt_deg": 5},
    "map.json": {"mode": "map", "surface": True, "surface_offset": 0.5, "width": 32,
                 "height": 32, "view_first": 1, "view_last": 8, "preview": True},
    "pick.json": {"u": 16.5, "v": 10.25, "focal_height": 0.0, "width": 32, "height": 32},
    "export.json": {"format": "tiff", "width": 32, "height": 32, "tilt_x_deg": 10,
                    "pan_x": 1.5},
    "command.json": {"width": 32, "height": 32, "pose_view": 4, "fov_deg": 40,
                     "aperture_radius": 3.0},
    "ws_render.json": {"type": "render", "id": 1,
                       "params": {"width": 32, "height": 32, "focal_height": 1.0,
                                  "colormap": "iron", "preview": False}},
    "ws_allinfocus.json": {"type": "allinfocus", "id": "aif", "first_height": -1.0,
                           "last_height": 4.0, "slices": 3, "params": {"width": 32, "height": 32}},
    "ws_stack.json": {"type": "stack", "id": 3, "first_height": 0.0, "last_height": 2.0,
                      "slices": 2, "params": {"width": 16, "height": 16}},
}
# HTTP method and path of each viewer/*.json that is not a WebSocket message.
VIEWER_ENDPOINTS = {"render.json": ("POST", "/api/render"), "map.json": ("POST", "/api/render"),
                    "pick.json": ("GET", "/api/pick"), "export.json": ("GET", "/api/export"),
                    "command.json": ("GET", "/api/command")}


def write_viewer_requests(folder: Path) -> None:
    folder.mkdir()
    for name, document in VIEWER_REQUESTS.items():
        (folder / name).write_text(json.dumps(document, indent=1) + "\n")


CAMERA_FILE = {"format": "aos-camera", "version": 1, "model": "radtan", "width": IMAGE_SIZE,
               "height": IMAGE_SIZE, "fx": 30.0, "fy": 30.0, "cx": 16.0, "cy": 16.0,
               "distortion": [0.01, 0.0, 0.0, 0.0, 0.0], "xi": 0.0, "skew": 0.0}


# =============================================================================================
# The campaign and its report.

@dataclasses.dataclass
class Campaign:
    seed: int
    targets: list[Target]
    outcomes: list[Outcome] = dataclasses.field(default_factory=list)
    saved: dict[int, Path] = dataclasses.field(default_factory=dict)
    wall_s: float = 0.0
    jobs: int = 1

    def counts(self) -> dict[str, dict[str, int]]:
        table = {t.name: dict.fromkeys(CLASSES, 0) for t in self.targets}
        for outcome in self.outcomes:
            table[outcome.case.target.name][outcome.cls] += 1
        return table

    def failures(self) -> list[Outcome]:
        return [o for o in self.outcomes if o.cls in FAILURE_CLASSES]

    def distinct(self) -> list[dict]:
        """Failures grouped by target, class and the detail with numbers and quoted values
        blanked; each group with its count and first case."""
        groups: dict[tuple, dict] = {}
        for outcome in self.failures():
            signature = re.sub(r"\d+", "N", outcome.detail)
            signature = re.sub(r"'[^']*'|\"[^\"]*\"", "'…'", signature)[:160]
            key = (outcome.case.target.name, outcome.cls, signature)
            group = groups.setdefault(key, {
                "target": key[0], "class": key[1], "signature": signature, "count": 0,
                "example_case": outcome.case.index, "example_detail": outcome.detail,
                "example_mutation": outcome.case.mutation,
                "reproducer": str(self.saved.get(outcome.case.index, ""))})
            group["count"] += 1
        return sorted(groups.values(), key=lambda g: (g["class"], g["target"], -g["count"]))

    def report(self) -> dict:
        totals = dict.fromkeys(CLASSES, 0)
        for outcome in self.outcomes:
            totals[outcome.cls] += 1
        return {"seed": self.seed, "cases": len(self.outcomes), "wall_s": round(self.wall_s, 1),
                "jobs": self.jobs, "classes": totals, "targets": self.counts(),
                "failures": len(self.failures()), "distinct_failures": self.distinct()}

    def table(self) -> str:
        short = {"ignores-sigterm": "no-term", "server-error": "server",
                 "multi-line-error": "multi", "unnamed-error": "unnamed",
                 "partial-output": "partial", "modified-input": "modified",
                 "accepted-invalid": "acc-inv"}
        columns = [short.get(c, c) for c in CLASSES]
        width = max(len(t.name) for t in self.targets) + 2
        lines = [f"{'target':<{width}}{'cases':>6}" + "".join(f"{c:>9}" for c in columns)]
        counts = self.counts()
        for name, row in counts.items():
            lines.append(f"{name:<{width}}{sum(row.values()):>6}" +
                         "".join(f"{row[c]:>9}" for c in CLASSES))
        totals = [sum(row[c] for row in counts.values()) for c in CLASSES]
        lines.append(f"{'total':<{width}}{len(self.outcomes):>6}" +
                     "".join(f"{n:>9}" for n in totals))
        lines.append(f"seed {self.seed}, {len(self.outcomes)} cases in {self.wall_s:.1f} s "
                     f"({self.jobs} job{'s' if self.jobs > 1 else ''}); "
                     f"{len(self.failures())} failures")
        for group in self.distinct():
            lines.append(f"  {group['class']:<17}{group['target']:<25} x{group['count']:<4} "
                         f"case {group['example_case']}: {group['example_detail'][:150]}")
        return "\n".join(lines)


def run_campaign(fuzzer: Fuzzer, args, targets: list[Target]) -> Campaign:
    campaign = Campaign(args.seed, targets, jobs=args.jobs)
    start = time.monotonic()
    deadline = start + args.time_limit
    indices = [args.case] if args.case is not None else list(range(args.cases))
    minimised_per_group: dict[tuple, int] = {}
    replay = ["python3", "tools/fuzz.py", "--seed", str(args.seed),
              "--aos-render", fuzzer.aos_render]
    if fuzzer.python_path:
        replay += ["--python-path", fuzzer.python_path]
    if args.targets:
        replay += ["--targets", ",".join(t.name for t in targets)]
    out = Path(args.out)
    lock = threading.Lock()

    def one(index: int) -> Optional[Outcome]:
        if time.monotonic() > deadline:
            return None
        case = fuzzer.make_case(args.seed, index, targets)
        outcome = fuzzer.execute(case)
        if outcome.cls in FAILURE_CLASSES:
            with lock:
                key = (case.target.name, outcome.cls)
                minimise = (case.kind == "bytes" and args.minimise_time > 0
                            and minimised_per_group.get(key, 0) < args.minimise_per_class)
                if minimise:
                    minimised_per_group[key] = minimised_per_group.get(key, 0) + 1
            data = case.data
            if minimise:
                data = fuzzer.minimise(outcome, min(args.minimise_time,
                                                    max(deadline - time.monotonic(), 0)))
            folder = fuzzer.save(outcome, data, minimise, args.seed, out, shlex.join(replay))
            with lock:
                campaign.saved[index] = folder
        if args.verbose:
            print(f"case {index} {case.target.name}: {outcome.cls} {outcome.detail[:120]} "
                  f"[{case.mutation[:80]}]", file=sys.stderr, flush=True)
        elif index % 100 == 99:
            print(f"fuzz.py: {index + 1} cases, {time.monotonic() - start:.0f} s",
                  file=sys.stderr, flush=True)
        return outcome

    with concurrent.futures.ThreadPoolExecutor(max_workers=args.jobs) as pool:
        for outcome in pool.map(one, indices):
            if outcome is not None:
                campaign.outcomes.append(outcome)
    campaign.wall_s = time.monotonic() - start
    return campaign


def parse_args(argv: Optional[list[str]] = None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seed", type=int, default=1, help="campaign seed (default 1)")
    parser.add_argument("--cases", type=int, default=300, help="number of cases (default 300)")
    parser.add_argument("--case", type=int, help="run only this case index (replay)")
    parser.add_argument("--time-limit", type=float, default=600,
                        help="stop starting cases after this many seconds (default 600)")
    parser.add_argument("--targets", help="comma list of targets or families (default: all)")
    parser.add_argument("--aos-render", default=shutil.which("aos-render"),
                        help="the aos-render to fuzz (default: the one on PATH)")
    parser.add_argument("--python-path", help="folder holding the aos package to fuzz "
                        "(prepended to PYTHONPATH; default: the installed aos)")
    parser.add_argument("--out", default="fuzz-out", help="reproducer folder (default fuzz-out)")
    parser.add_argument("--jobs", type=int, default=1, help="cases run at once (default 1)")
    parser.add_argument("--timeout", type=float, default=10.0, help="seconds per run (default 10)")
    parser.add_argument("--term-grace", type=float, default=2.0,
                        help="seconds from the timeout's SIGTERM to SIGKILL; a run that needs "
                             "the SIGKILL is an ignores-sigterm failure (default 2)")
    parser.add_argument("--memory-limit-mb", type=int, default=4096,
                        help="RLIMIT_AS of every run, MiB (default 4096)")
    parser.add_argument("--rss-limit-mb", type=int, default=1024,
                        help="peak resident memory above this is a failure, MiB (default 1024)")
    parser.add_argument("--minimise-time", type=float, default=20.0,
                        help="seconds of delta debugging per saved case (0: off; default 20)")
    parser.add_argument("--minimise-per-class", type=int, default=2,
                        help="cases minimised per target and class; the rest are saved as "
                             "found (default 2)")
    parser.add_argument("--json", action="store_true", help="print the report as JSON")
    parser.add_argument("--verbose", action="store_true", help="one line per case on stderr")
    parser.add_argument("--list-targets", action="store_true", help="list the targets and exit")
    parser.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    return parser.parse_args(argv)


def main(argv: Optional[list[str]] = None) -> int:
    args = parse_args(argv)
    args.verbose = args.verbose or args.case is not None
    if args.worker:
        worker_main()
        return 0
    # SIGTERM unwinds like Ctrl-C: running cases end, temporary folders are removed.
    signal.signal(signal.SIGTERM, signal.default_int_handler)
    if args.list_targets:
        for target in TARGETS:
            print(f"{target.name:<26}{target.kind:<8}{', '.join(target.files)}")
        return 0
    targets = select_targets(args.targets)
    if not args.aos_render or not shutil.which(args.aos_render):
        print("fuzz.py: error: no aos-render (give --aos-render)", file=sys.stderr)
        return 2
    limits = Limits(args.timeout, args.memory_limit_mb, args.rss_limit_mb, args.term_grace)
    out = Path(args.out)
    with tempfile.TemporaryDirectory(prefix="aos-fuzz-") as tmp:
        fuzzer = Fuzzer(os.path.abspath(shutil.which(args.aos_render)), args.python_path, limits,
                        Path(tmp))
        try:
            try:
                fuzzer.build_corpus()
                broken = fuzzer.check_corpus(targets, args.jobs)
            except RuntimeError as error:   # the corpus, the Python worker or the viewer
                print(f"fuzz.py: error: set-up failed: {error}", file=sys.stderr)
                return 2
            if broken:
                for outcome in broken:
                    print(f"fuzz.py: error: the unmutated corpus is not ok for "
                          f"{outcome.case.target.name} ({outcome.case.file}): {outcome.cls}: "
                          f"{outcome.detail}", file=sys.stderr)
                return 2
            out.mkdir(parents=True, exist_ok=True)
            shutil.rmtree(out / "corpus", ignore_errors=True)
            shutil.copytree(fuzzer.corpus, out / "corpus", symlinks=True)
            campaign = run_campaign(fuzzer, args, targets)
        finally:
            fuzzer.close()
    report = campaign.report()
    (out / "report.json").write_text(json.dumps(report, indent=2) + "\n")
    print(json.dumps(report, indent=2) if args.json else campaign.table())
    return 1 if campaign.failures() else 0


if __name__ == "__main__":
    sys.exit(main())
