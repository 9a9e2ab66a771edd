"""`physcap calibrate board`: the PDF read back (its page, the board image and where it is
drawn, the scale bar) finds the squares at the stated size at 1:1; `--square-mm`."""

from __future__ import annotations

import re
import zlib

import numpy as np
import pytest
from typer.testing import CliRunner

from physcap_drake.cli import app
from physcap_drake.perception import charuco
from physcap_drake.perception.printed_boards import (
    HAND_EYE_A4,
    TABLE_A3,
    measured_board,
)

POINTS_PER_MM = 72.0 / 25.4
#: ISO 216 paper sizes, landscape, mm.
PAPER_MM = {"A3": (420.0, 297.0), "A4": (297.0, 210.0)}


def _unfilter_png_rows(raw: bytes, stride: int, rows: int) -> np.ndarray:
    """Undoes the PNG row filters (a PDF FlateDecode stream with a PNG predictor)."""
    out = np.zeros((rows, stride), dtype=np.uint8)
    previous = np.zeros(stride, dtype=np.int32)
    for row in range(rows):
        start = row * (stride + 1)
        kind, line = raw[start], np.frombuffer(raw[start + 1:start + 1 + stride], np.uint8)
        line = line.astype(np.int32)
        if kind == 0:
            current = line
        elif kind == 2:
            current = (line + previous) % 256
        else:  # 1-bit images: sub, average and Paeth reduce to byte-wise sums here
            current = np.zeros(stride, dtype=np.int32)
            for i in range(stride):
                left = current[i - 1] if i else 0
                up, up_left = previous[i], previous[i - 1] if i else 0
                if kind == 1:
                    predicted = left
                elif kind == 3:
                    predicted = (left + up) // 2
                else:
                    p = left + up - up_left
                    predicted = min((abs(p - left), 0, left), (abs(p - up), 1, up),
                                    (abs(p - up_left), 2, up_left))[2]
                current[i] = (line[i] + predicted) % 256
        out[row] = current
        previous = current
    return out


def _inflate_after(data: bytes, start: int) -> bytes:
    """The FlateDecode stream that begins at `start` (trailing bytes ignored)."""
    return zlib.decompressobj().decompress(data[start:])


def read_board_pdf(path) -> dict:
    """The page size (pt), the board image (grey, 0 black) and the rectangle it is drawn in
    (x, y, width, height in pt), and the drawn straight segments (pt), from the PDF."""
    data = path.read_bytes()
    pages = re.findall(rb"/Type /Page\b", data)
    media = [float(v) for v in re.search(rb"/MediaBox \[ ([\d. ]+) \]", data).group(1).split()]
    header = re.search(rb"/Subtype /Image /Width (\d+) /Height (\d+)(.*?)>>\s*stream\n", data,
                       re.S)
    width, height = int(header.group(1)), int(header.group(2))
    bits = int(re.search(rb"/BitsPerComponent (\d+)", header.group(3)).group(1))
    rows = _unfilter_png_rows(_inflate_after(data, header.end()), (width * bits + 7) // 8,
                              height)
    if bits == 1:  # indexed: 0 white, 1 black (matplotlib's two-colour palette)
        assert b"(\xff\xff\xff\x00\x00\x00)" in header.group(3)
        image = (1 - np.unpackbits(rows, axis=1)[:, :width]) * 255
    else:
        image = rows[:, :width]
    number = int(re.search(rb"/Contents (\d+) 0 R", data).group(1))
    body = re.search(rb"\n%d 0 obj\n<<[^>]*>>\nstream\n" % number, data)
    contents = _inflate_after(data, body.end())
    drawn = contents[:contents.index(b"/I1 Do")]
    drawn = drawn[drawn.rindex(b"q "):]  # the image's own graphics state
    matrix = np.eye(3)
    for numbers in re.findall(rb"((?:[\d.\-]+\s+){6})cm", drawn):
        a, b, c, d, e, f = (float(v) for v in numbers.split())
        # A later `cm` acts on the image's points first.
        matrix = matrix @ np.array([[a, c, e], [b, d, f], [0, 0, 1]])
    corners = matrix @ np.array([[0, 1], [0, 1], [1, 1]], dtype=float)  # (0,0) and (1,1)
    x0, x1 = sorted(corners[0])
    y0, y1 = sorted(corners[1])
    e, f, a, d = x0, media[3] - y1, x1 - x0, y1 - y0  # from the page's top-left, pt
    # The image's first row is at v = 1 of the unit square, its first column at u = 0:
    # show it as the page does (a mirrored board is not a board to the detector).
    (u0_x, v1_y), (u1_x, v0_y) = (matrix @ [0, 1, 1])[:2], (matrix @ [1, 0, 1])[:2]
    image = image[::1 if v1_y > v0_y else -1, ::1 if u1_x > u0_x else -1]
    segments = [tuple(float(v) for v in m.groups()) for m in re.finditer(
        rb"([\d.\-]+) ([\d.\-]+) m\n([\d.\-]+) ([\d.\-]+) l\n", contents)]
    return {"pages": len(pages), "page_pt": media[2:], "image": image.astype(np.uint8),
            "drawn_pt": (e, f, a, d), "segments": segments}


def square_size_mm(pdf: dict, spec: charuco.BoardSpec) -> float:
    """The side of a square as printed, mm: the corners the ChArUco detector finds in the
    board image, their spacing in image pixels, and the size the page draws a pixel at."""
    grey = pdf["image"]
    padded = np.pad(grey, 40, constant_values=255)  # the detector wants a quiet zone
    ids, pixels = charuco.detect_corners(np.dstack([padded] * 3), spec)
    assert len(ids) == (spec.squares[0] - 1) * (spec.squares[1] - 1)
    board = charuco.corner_points(spec)[ids, :2]
    # Scale (px per m) of the similarity that maps the board's corners to the pixels.
    centred_px = pixels - pixels.mean(axis=0)
    centred_b = board - board.mean(axis=0)
    px_per_m = np.sqrt((centred_px ** 2).sum() / (centred_b ** 2).sum())
    _, _, width_pt, _ = pdf["drawn_pt"]
    mm_per_px = width_pt / grey.shape[1] / POINTS_PER_MM
    return px_per_m * spec.square * mm_per_px


@pytest.mark.parametrize(("paper", "printed"), [("A4", HAND_EYE_A4), ("A3", TABLE_A3)])
def test_the_printed_board_has_its_squares_at_the_stated_size(tmp_path, paper, printed):
    out = tmp_path / "b.pdf"
    result = CliRunner().invoke(app, ["calibrate", "board", "--paper", paper, "--out",
                                      str(out)])
    assert result.exit_code == 0, result.output
    pdf = read_board_pdf(out)
    assert pdf["pages"] == 1
    assert np.allclose(np.array(pdf["page_pt"]) / POINTS_PER_MM, PAPER_MM[paper], atol=0.1)
    stated = float(re.search(r"squares of ([\d.]+) mm", result.output).group(1))
    assert stated == pytest.approx(1000 * printed.spec.square)
    assert square_size_mm(pdf, printed.spec) == pytest.approx(stated, abs=0.1)
    # Margins: the board lies inside the page, at least 10 mm from every edge.
    x, y, w, h = pdf["drawn_pt"]
    page_w, page_h = pdf["page_pt"]
    assert min(x, y, page_w - x - w, page_h - y - h) / POINTS_PER_MM >= 10.0
    # The scale bar: a horizontal segment 100 mm long.
    lengths = [abs(x1 - x0) / POINTS_PER_MM for x0, y0, x1, y1 in pdf["segments"]
               if abs(y1 - y0) < 1e-6]
    assert any(abs(length - 100.0) < 0.05 for length in lengths)


def test_a_measured_square_more_than_five_percent_off_is_refused():
    nominal = 1000 * TABLE_A3.spec.square
    assert measured_board(TABLE_A3, nominal * 1.04).square == pytest.approx(nominal * 1.04e-3)
    assert measured_board(TABLE_A3, None) == TABLE_A3.spec
    scaled = measured_board(TABLE_A3, nominal * 0.97)
    assert scaled.marker / scaled.square == pytest.approx(TABLE_A3.spec.marker
                                                          / TABLE_A3.spec.square)
    for off in (nominal * 1.06, nominal * 0.94, 0.0):
        with pytest.raises(ValueError, match="print"):
            measured_board(TABLE_A3, off)


def test_calibrate_camera_refuses_a_bad_square_size():
    result = CliRunner().invoke(app, ["calibrate", "camera", "--square-mm", "47"])
    assert result.exit_code == 2 and "model" in result.output  # simulation: not a print
