"""The ChArUco boards a rig's owner prints at 1:1: an A3 board laid on the table and an A4
board the PiPER's gripper clamps by a short edge, as PDF pages with margins, crop marks, a
100 mm scale bar and the board's parameters."""

from __future__ import annotations

import dataclasses as dc
from pathlib import Path

import numpy as np

from physcap_drake.perception.charuco import DICTIONARY, BoardSpec, board_image

#: Paper sizes, landscape (width, height), mm.
PAPERS = {"A3": (420.0, 297.0), "A4": (297.0, 210.0)}
MM_PER_INCH = 25.4
#: Rendered pixels per mm of board (a multiple of the markers' cells lands on whole pixels).
PIXELS_PER_MM = 12
#: Length of the scale bar, mm.
SCALE_BAR = 100.0
#: A measured square may differ from the nominal by at most this share.
MAX_SCALE_ERROR = 0.05


@dc.dataclass(frozen=True)
class PrintedBoard:
    """A board to print: its layout (m), the paper, where its top-left corner sits on the
    page (mm from the page's left and top edges), and the blank tab (mm) beyond its right
    short edge that the gripper clamps (0: none)."""

    name: str
    paper: str
    spec: BoardSpec
    origin_mm: tuple[float, float]
    clamp_tab_mm: float = 0.0


#: The table board: 6 x 4 squares of 50 mm (300 x 200 mm) on A3.
TABLE_A3 = PrintedBoard("table", "A3", BoardSpec((6, 4), 0.050, 0.0375), (40.0, 30.0))
#: The hand-eye board: 6 x 4 squares of 28 mm (168 x 112 mm) and a 40 mm clamping tab on
#: A4; glued to 3-5 mm foam board it weighs about 50 g and stays flat in the fingers.
HAND_EYE_A4 = PrintedBoard("hand-eye", "A4", BoardSpec((6, 4), 0.028, 0.021), (25.0, 25.0),
                           clamp_tab_mm=40.0)
BOARDS = {"A3": TABLE_A3, "A4": HAND_EYE_A4}


def measured_board(printed: PrintedBoard, square_mm: float | None) -> BoardSpec:
    """The board as printed, with the square side measured on the print (mm; None: the
    nominal). Raises ValueError if it is more than MAX_SCALE_ERROR off the nominal."""
    if square_mm is None:
        return printed.spec
    nominal = 1000.0 * printed.spec.square
    if not square_mm > 0.0 or abs(square_mm / nominal - 1.0) > MAX_SCALE_ERROR:
        raise ValueError(
            f"--square-mm {square_mm:g}: the {printed.name} board's squares are {nominal:g} mm; "
            f"a print more than {MAX_SCALE_ERROR:.0%} off is not 1:1 (check the printer's "
            "scale: 'actual size' or 100 %, not 'fit to page'), or the wrong board was measured")
    return printed.spec.with_square(square_mm / 1000.0)


def write_board_pdf(printed: PrintedBoard, path: Path) -> None:
    """Writes `printed` as a one-page PDF at 1:1 (a page of its paper size, landscape)."""
    import matplotlib  # noqa: PLC0415 (plotting is optional work)

    matplotlib.use("Agg")
    from matplotlib.figure import Figure  # noqa: PLC0415

    page_w, page_h = PAPERS[printed.paper]
    figure = Figure(figsize=(page_w / MM_PER_INCH, page_h / MM_PER_INCH))
    axes = figure.add_axes((0.0, 0.0, 1.0, 1.0))
    axes.set_xlim(0.0, page_w)
    axes.set_ylim(page_h, 0.0)  # mm from the top-left corner, y down
    axes.axis("off")
    spec = printed.spec
    width, height = 1000.0 * spec.size[0], 1000.0 * spec.size[1]
    left, top = printed.origin_mm
    image = board_image(1000.0 * PIXELS_PER_MM, spec)
    axes.imshow(image, cmap="gray", vmin=0, vmax=255, interpolation="none",
                extent=(left, left + width, top + height, top))
    _crop_marks(axes, left, top, width + printed.clamp_tab_mm, height)
    if printed.clamp_tab_mm:
        axes.text(left + width + printed.clamp_tab_mm / 2, top + height / 2,
                  "clamp here", rotation=90, ha="center", va="center", fontsize=9)
    bar_y = top + height + 22.0
    axes.plot([left, left + SCALE_BAR], [bar_y, bar_y], color="black", lw=1.5)
    for tick in np.arange(0.0, SCALE_BAR + 1e-9, 10.0):
        axes.plot([left + tick] * 2, [bar_y, bar_y - (4.0 if tick % 50 == 0 else 2.0)],
                  color="black", lw=0.8)
    axes.text(left + SCALE_BAR + 4.0, bar_y, "100 mm: measure it, and one square",
              va="center", fontsize=8)
    axes.text(left, bar_y + 8.0, parameters_text(printed), va="top", fontsize=8,
              family="monospace")
    figure.savefig(path, format="pdf")


def parameters_text(printed: PrintedBoard) -> str:
    spec = printed.spec
    return (f"physcap {printed.name} board, {printed.paper} landscape, print at 100 % (actual "
            f"size). ChArUco {spec.squares[0]} x {spec.squares[1]} squares of "
            f"{1000 * spec.square:g} mm, markers {1000 * spec.marker:g} mm, dictionary "
            f"DICT_4X4_50 (id {DICTIONARY}).\nMeasure a square; pass it as "
            "`physcap calibrate camera --square-mm S`.")


def _crop_marks(axes, left: float, top: float, width: float, height: float) -> None:
    length, gap = 6.0, 2.0
    for x, sx in ((left, -1), (left + width, 1)):
        for y, sy in ((top, -1), (top + height, 1)):
            axes.plot([x + sx * gap, x + sx * (gap + length)], [y, y], color="black", lw=0.4)
            axes.plot([x, x], [y + sy * gap, y + sy * (gap + length)], color="black", lw=0.4)
