"""The Pin array touch component's dialog as pictures for the docs, drawn from its parameters:
each tab Builder shows, in Builder's order, each field with its label, its control (text box,
file box, drop-down, check box) holding an example experiment's value, and its hint (Builder
shows it as a tooltip). One picture per example: a protocol's stimulus by name
(psychopy_congruency), and a pattern built in the dialog without a protocol (psychopy_patterns).

    .venv-psychopy/bin/python tests/psychopy/dialog_picture.py     # writes the pictures

A screenshot needs Builder's app (wx), which psychopy-lib does not have: this picture is drawn
from the same `Param`s the dialog is built from, and tests/psychopy/test_builder.py checks that
the committed files are what the component's parameters draw now.
"""

from __future__ import annotations

import textwrap
from pathlib import Path
from xml.sax.saxutils import escape

REPO = Path(__file__).resolve().parents[2]
DOCS = REPO / "docs" / "programmers"
EXAMPLES = REPO / "examples"
PICTURES = {  # the example experiment -> the picture of its Pin array touch's dialog
    EXAMPLES / "psychopy_congruency.psyexp": DOCS / "pin-array-touch-dialog.svg",
    EXAMPLES / "psychopy_patterns.psyexp": DOCS / "pin-array-touch-pattern-dialog.svg",
}
TABS = ("Basic", "Device", "Stimulus", "Data")

WIDTH = 760
LABEL_X, CONTROL_X, CONTROL_W = 24, 250, 300
ROW_H, HINT_LINE_H, TAB_H = 30, 15, 36
FONT = "font-family='DejaVu Sans, Arial, sans-serif'"


def example_component(example: Path):
    """The Pin array touch of the ``example`` experiment, as Builder loads it."""
    from psychopy import experiment, plugins

    plugins.activatePlugins()
    exp = experiment.Experiment()
    exp.loadFromXML(str(example))
    for routine in exp.routines.values():
        for component in routine:
            if type(component).__name__ == "PinArrayTouchComponent":
                return component
    raise LookupError(f"no Pin array touch in {example}")


def fields(component) -> dict[str, list[tuple[str, object]]]:
    """{tab: [(name, param), ...]} in Builder's order: the component's order, then the rest;
    the name heads the first tab, and a start or stop time and its type are one field, as
    Builder shows them."""
    names = [name for name in component.order if name in component.params]
    names += [name for name in component.params if name not in names]
    tabs: dict[str, list[tuple[str, object]]] = {tab: [] for tab in TABS}
    for name in names:
        param = component.params[name]
        if name == "name":
            tabs["Basic"].insert(0, (name, param))
        elif param.categ is not None and name not in ("startType", "stopType"):
            tabs.setdefault(param.categ, []).append((name, param))
    return tabs


def control(name: str, param, component, y: int) -> str:
    """The SVG of one field's control at height ``y``."""
    value = "" if param.val is None else str(param.val)
    x, h = CONTROL_X, ROW_H - 8
    if param.inputType == "bool":
        tick = (f"<path d='M{x + 4} {y + 11} l5 5 l9 -11' stroke='#1a73e8' stroke-width='2.5' "
                "fill='none'/>" if param.val in (True, "True") else "")
        return (f"<rect x='{x}' y='{y + 2}' width='18' height='18' rx='3' fill='white' "
                f"stroke='#80868b'/>{tick}")
    kind = {"startVal": "startType", "stopVal": "stopType"}.get(name)
    parts = []
    if kind is not None:  # the type's drop-down, then the value's box
        parts.append(dropdown(x, y, 130, str(component.params[kind].val)))
        x, width = x + 138, CONTROL_W - 138
    else:
        width = CONTROL_W
    if param.inputType in ("choice", "device"):
        parts.append(dropdown(x, y, width, value))
    else:
        parts.append(f"<rect x='{x}' y='{y}' width='{width}' height='{h}' rx='3' "
                     f"fill='white' stroke='#80868b'/>"
                     f"<text x='{x + 6}' y='{y + 15}' font-size='12' {FONT}>"
                     f"{escape(value)}</text>")
        if param.inputType == "file":
            parts.append(f"<rect x='{x + width + 6}' y='{y}' width='28' height='{h}' rx='3' "
                         f"fill='#f1f3f4' stroke='#80868b'/><text x='{x + width + 13}' "
                         f"y='{y + 15}' font-size='12' {FONT}>...</text>")
    return "".join(parts)


def dropdown(x: int, y: int, width: int, value: str) -> str:
    return (f"<rect x='{x}' y='{y}' width='{width}' height='{ROW_H - 8}' rx='3' fill='#f8f9fa' "
            f"stroke='#80868b'/><text x='{x + 6}' y='{y + 15}' font-size='12' {FONT}>"
            f"{escape(value)}</text><path d='M{x + width - 16} {y + 9} l5 5 l5 -5' "
            "stroke='#3c4043' fill='none'/>")


def picture(component) -> str:
    """The whole dialog, one tab under the other, as SVG text."""
    body: list[str] = []
    y = 56
    for tab, rows in fields(component).items():
        if not rows:
            continue
        body.append(f"<rect x='12' y='{y}' width='{WIDTH - 24}' height='{TAB_H - 8}' rx='4' "
                    f"fill='#e8f0fe'/><text x='{LABEL_X}' y='{y + 19}' font-size='14' "
                    f"font-weight='bold' {FONT}>{escape(tab)}</text>")
        y += TAB_H
        for name, param in rows:
            body.append(f"<text x='{LABEL_X}' y='{y + 15}' font-size='12' {FONT}>"
                        f"{escape(str(param.label))}</text>")
            body.append(control(name, param, component, y))
            y += ROW_H - 4
            for line in textwrap.wrap(str(param.hint), 104):
                body.append(f"<text x='{LABEL_X + 12}' y='{y + 10}' font-size='10.5' "
                            f"fill='#5f6368' {FONT}>{escape(line)}</text>")
                y += HINT_LINE_H
            y += 10
        y += 6
    height = y + 12
    title = f"{component.params['name'].val} Properties (Pin array touch)"
    return (f"<svg xmlns='http://www.w3.org/2000/svg' width='{WIDTH}' height='{height}' "
            f"viewBox='0 0 {WIDTH} {height}'>\n"
            f"<title>{escape(title)}: drawn from the component's parameters</title>\n"
            f"<rect width='{WIDTH}' height='{height}' rx='8' fill='white' stroke='#dadce0'/>\n"
            f"<rect width='{WIDTH}' height='40' rx='8' fill='#3c4043'/>\n"
            f"<text x='{LABEL_X}' y='26' font-size='15' fill='white' {FONT}>"
            f"{escape(title)}</text>\n" + "\n".join(body) + "\n</svg>\n")


def main() -> None:
    for example, drawn in PICTURES.items():
        drawn.write_text(picture(example_component(example)), encoding="utf-8")


if __name__ == "__main__":
    main()
