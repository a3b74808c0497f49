"""Fitting the panel's words to the sidebar's width, measured with Blender's own font metrics (blf).

Blender cuts a label that does not fit ("Key: bunny.pmwm-key.js..."), and a property's name beside
its field gets 40 % of the row (property split). The panels ask here how many pixels a piece of text
has and wrap their sentences to it, break a long file name, and put a property's name on a line of
its own when it would be cut beside the field. Widths are in region pixels, so they follow the
interface scale (Preferences > Interface > Resolution Scale).

The room of each kind of text is the region width less Blender's margins (category tabs, panel
margins and text padding); the margins below reproduce where a Blender 4.2 window at its default
sidebar width cut the add-on's earlier labels, and are scaled by the interface scale.
"""

from __future__ import annotations

from dataclasses import dataclass

import blf

FONT = 0  # the interface font
POINTS = 11.0  # Blender's default text size (UI_DEFAULT_TEXT_POINTS)
DEFAULT_WIDTH = 220  # the sidebar's default width at scale 1 (UI_SIDEBAR_PANEL_WIDTH)
SPLIT = 0.4  # the share of a row for a property's name (UI_ITEM_PROP_SEP_DIVIDE)

# Margins at scale 1, in pixels.
PANEL_MARGIN = 30  # region edge, category tabs, panel border: region width -> the panel's content
TEXT_MARGIN = 20  # text padding of a label
ICON = 24  # an icon before a label's text
BOX = 16  # a box's border on both sides
SPLIT_MARGIN = 2  # padding of a property's name in its column
FIELD_MARGIN = 24  # a drop-down's arrow or a button's padding


def scale(context) -> float:
    """The interface scale (the Resolution Scale times the display's pixel density)."""
    prefs = getattr(context, "preferences", None)
    system = getattr(prefs, "system", None)
    value = getattr(system, "ui_scale", 0.0) or getattr(getattr(prefs, "view", None), "ui_scale", 1.0)
    return float(value or 1.0)


def text_width(text: str, ui_scale: float = 1.0) -> float:
    """Width in pixels of ``text`` drawn in the interface font at the interface scale."""
    blf.size(FONT, POINTS * ui_scale)
    return float(blf.dimensions(FONT, text)[0])


@dataclass(frozen=True)
class Room:
    """Pixels for text in one panel drawn in a region ``width`` pixels wide at ``ui_scale``."""

    width: float
    ui_scale: float = 1.0
    boxes: int = 0  # nesting in boxes

    @classmethod
    def of(cls, context) -> "Room":
        s = scale(context)
        region = getattr(context, "region", None)
        width = getattr(region, "width", 0) or DEFAULT_WIDTH * s
        return cls(float(width), s)

    def boxed(self) -> "Room":
        return Room(self.width, self.ui_scale, self.boxes + 1)

    @property
    def content(self) -> float:
        return self.width - (PANEL_MARGIN + BOX * self.boxes) * self.ui_scale

    def label(self, icon: bool = False) -> float:
        """Room for a label's text (with an icon before it or not)."""
        return self.content - (TEXT_MARGIN + (ICON if icon else 0)) * self.ui_scale

    def split_name(self) -> float:
        """Room for a property's name left of its field (property split)."""
        return SPLIT * self.content - SPLIT_MARGIN * self.ui_scale

    def field(self, split: bool = True) -> float:
        """Room for the text inside a field or button (beside its name when ``split``)."""
        return (1 - SPLIT if split else 1.0) * self.content - FIELD_MARGIN * self.ui_scale

    def fits(self, text: str, room: float) -> bool:
        return text_width(text, self.ui_scale) <= room


def _break_word(word: str, room: float, ui_scale: float) -> list[str]:
    """A word too long for a line (a file name, a path), cut into pieces that fit."""
    pieces, piece = [], ""
    for ch in word:
        if piece and text_width(piece + ch, ui_scale) > room:
            pieces.append(piece)
            piece = ch
        else:
            piece += ch
    return pieces + ([piece] if piece else [])


def wrap(text: str, room: float, ui_scale: float = 1.0) -> list[str]:
    """``text`` in lines that each fit ``room`` pixels: broken between words, and inside a word
    only when the word alone is too long. Narrower than a few letters, the text stays one line (Blender
    clips it)."""
    if room < text_width("MMM", ui_scale):
        return [text]
    lines: list[str] = []
    line = ""
    for word in text.split():
        candidate = f"{line} {word}" if line else word
        if text_width(candidate, ui_scale) <= room:
            line = candidate
            continue
        if line:
            lines.append(line)
        if text_width(word, ui_scale) <= room:
            line = word
        else:
            *whole, line = _break_word(word, room, ui_scale)
            lines.extend(whole)
    if line or not lines:
        lines.append(line)
    return lines
