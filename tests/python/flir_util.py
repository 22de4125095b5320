"""FLIR radiometric JPEGs for tests: a known temperature image turned into raw counts by FLIR's
published model (Planck relation, emissivity, atmosphere, window), written in FLIR's FFF layout
(a record directory with RawData and CameraInfo records, as ExifTool's FLIR module reads it) into
the APP1 "FLIR" segments of a JPEG. Written here, independently of aos's own conversion
(cpp/aos/image/flir.cpp), so that a test of aos against it is not circular."""

from __future__ import annotations

import math
import struct
from pathlib import Path

import numpy as np

import aos

ZERO_C = 273.15

# Constants of a typical FLIR core (ExifTool's defaults for the atmosphere; Planck constants as
# FLIR Duo/Vue cameras store them). Floats are stored as float32: the test compares against the
# rounded values the file holds.
CALIBRATION = {
    "R1": 21106.77, "R2": 0.012545258, "B": 1501.0, "F": 1.0, "O": -7340,
    "emissivity": 0.95, "distance_m": 30.0, "reflected_c": 20.0, "air_c": 15.0,
    "window_c": 20.0, "window_transmission": 1.0, "humidity": 0.5,
    "alpha1": 0.006569, "alpha2": 0.01262, "beta1": -0.002276, "beta2": -0.00667, "x": 1.9,
}


def stored(calibration: dict[str, float]) -> dict[str, float]:
    """The calibration as the file holds it (float32, PlanckO an integer)."""
    return {k: (int(v) if k == "O" else float(np.float32(v))) for k, v in calibration.items()}


def _black_body(kelvin, c):
    return c["R1"] / (c["R2"] * (np.exp(c["B"] / kelvin) - c["F"])) - c["O"]


def _air(c):
    t = float(np.float32(c["air_c"] + ZERO_C)) - ZERO_C
    water = c["humidity"] * math.exp(1.5587 + 0.06939 * t - 0.00027816 * t ** 2
                                     + 0.00000068455 * t ** 3)
    d = math.sqrt(c["distance_m"] / 2.0)
    return (c["x"] * math.exp(-d * (c["alpha1"] + c["beta1"] * math.sqrt(water)))
            + (1 - c["x"]) * math.exp(-d * (c["alpha2"] + c["beta2"] * math.sqrt(water))))


def _kelvin(c, key):
    # Temperatures are stored as float32 kelvin.
    return float(np.float32(c[key] + ZERO_C))


def raw_of_kelvin(kelvin: np.ndarray, c: dict[str, float]) -> np.ndarray:
    """What the camera reports for an object at `kelvin`: the object's radiance through air,
    window and air, plus what the reflected scene, the air and the window add."""
    tau, w, e = _air(c), c["window_transmission"], c["emissivity"]
    reflected = _black_body(_kelvin(c, "reflected_c"), c)
    air = _black_body(_kelvin(c, "air_c"), c)
    window = _black_body(_kelvin(c, "window_c"), c)
    at_window = tau * (e * _black_body(kelvin, c) + (1 - e) * reflected) + (1 - tau) * air
    return tau * (w * at_window + (1 - w) * window) + (1 - tau) * air


def kelvin_of_raw(raw: np.ndarray, c: dict[str, float]) -> np.ndarray:
    """The inverse of raw_of_kelvin, peeled layer by layer."""
    tau, w, e = _air(c), c["window_transmission"], c["emissivity"]
    reflected = _black_body(_kelvin(c, "reflected_c"), c)
    air = _black_body(_kelvin(c, "air_c"), c)
    window = _black_body(_kelvin(c, "window_c"), c)
    at_camera_side = (np.asarray(raw, float) - (1 - tau) * air) / tau
    at_window = (at_camera_side - (1 - w) * window) / w
    at_object = ((at_window - (1 - tau) * air) / tau - (1 - e) * reflected) / e
    return c["B"] / np.log(c["R1"] / (c["R2"] * (at_object + c["O"])) + c["F"])


def _fff(raw: np.ndarray, c: dict[str, float], png: bool, folder: Path,
         swap_png: bool = True) -> bytes:
    height, width = raw.shape
    if png:
        # FLIR's PNGs hold little-endian counts in a big-endian PNG: the bytes appear swapped
        # (swap_png False writes them in the PNG's own order, as some tools do).
        swapped = ((raw >> 8) | (raw << 8)).astype(np.uint16) if swap_png else raw
        path = folder / "_raw.png"
        aos.write_image(str(path), swapped)
        data = path.read_bytes()
        path.unlink()
    else:
        data = raw.astype("<u2").tobytes()
    words = [2, width, height, 0, 0, 0, width - 1, 0, height - 1] + [0] * 7
    raw_record = struct.pack("<16H", *words) + data
    info = bytearray(0x400)
    struct.pack_into("<H", info, 0, 2)
    for offset, value in [(0x20, c["emissivity"]), (0x24, c["distance_m"]),
                          (0x28, c["reflected_c"] + ZERO_C), (0x2C, c["air_c"] + ZERO_C),
                          (0x30, c["window_c"] + ZERO_C), (0x34, c["window_transmission"]),
                          (0x3C, c["humidity"]), (0x58, c["R1"]), (0x5C, c["B"]),
                          (0x60, c["F"]), (0x70, c["alpha1"]), (0x74, c["alpha2"]),
                          (0x78, c["beta1"]), (0x7C, c["beta2"]), (0x80, c["x"]),
                          (0x30C, c["R2"])]:
        struct.pack_into("<f", info, offset, value)
    struct.pack_into("<i", info, 0x308, int(c["O"]))
    header = bytearray(0x40)
    header[0:4] = b"FFF\0"
    records = [(1, 3 if png else 2, raw_record), (0x20, 1, bytes(info))]
    struct.pack_into("<III", header, 0x14, 100, 0x40, len(records))
    directory = b""
    offset = 0x40 + 0x20 * len(records)
    body = b""
    for index, (kind, subtype, record) in enumerate(records):
        directory += struct.pack("<HHIIIIIII", kind, subtype, 0x64, index + 1, offset,
                                 len(record), 0, 0, 0)
        offset += len(record)
        body += record
    return bytes(header) + directory + body


def write_flir_jpeg(path: Path, celsius: np.ndarray, calibration: dict[str, float] = CALIBRATION,
                    png: bool = True, swap_png: bool = True) -> np.ndarray:
    """Writes a FLIR radiometric JPEG whose raw counts encode `celsius` (2-D); returns the
    integer counts written."""
    c = stored(calibration)
    raw = np.rint(raw_of_kelvin(np.asarray(celsius, float) + ZERO_C, c)).astype(np.uint16)
    fff = _fff(raw, c, png, path.parent, swap_png)
    visual = path.parent / "_visual.jpg"
    aos.write_image(str(visual), np.full((raw.shape[0], raw.shape[1], 3), 128, np.uint8))
    jpeg = visual.read_bytes()
    visual.unlink()
    chunk = 60000
    pieces = [fff[i:i + chunk] for i in range(0, len(fff), chunk)]
    segments = b""
    for index, piece in enumerate(pieces):
        payload = b"FLIR\0\x01" + bytes([index, len(pieces) - 1]) + piece
        segments += b"\xff\xe1" + struct.pack(">H", len(payload) + 2) + payload
    path.write_bytes(jpeg[:2] + segments + jpeg[2:])
    return raw
