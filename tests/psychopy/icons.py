"""Draw the Pin array touch component's icons (Builder's light, dark and classic themes, at 48
and 96 pixels): the 4x4 pins, three of a row raised as a wave runs along it.

    .venv-psychopy/bin/python tests/psychopy/icons.py

Run once when the picture changes; the PNG files are committed beside the component
(pinarray/psychopy/components/pinArrayTouch/), where PsychoPy looks for them.
"""

from pathlib import Path

from PIL import Image, ImageDraw

FOLDER = Path(__file__).resolve().parents[2] / "pinarray" / "psychopy" / "components" / "pinArrayTouch"
THEMES = {  # pin at rest, pin raised, frame
    "light": ("#9aa0a6", "#f2545b", "#5f6368"),
    "dark": ("#80868b", "#ff7b7f", "#dadce0"),
    "classic": ("#707070", "#d0343a", "#303030"),
}
RAISED = {5, 6, 7}  # pins 5 6 7: the second row from the bottom, as apparent_motion.yaml's wave


def draw(size: int, rest: str, raised: str, frame: str) -> Image.Image:
    image = Image.new("RGBA", (size, size), (0, 0, 0, 0))
    pen = ImageDraw.Draw(image)
    unit = size / 48
    pen.rounded_rectangle([2 * unit, 2 * unit, 46 * unit, 46 * unit], radius=6 * unit,
                          outline=frame, width=max(1, round(2 * unit)))
    for row in range(4):  # row 0 is the bottom row, as the subject sees the array
        for column in range(4):
            pin = row * 4 + column + 1
            x = (10 + column * 9.3) * unit
            y = (38 - row * 9.3) * unit
            radius = (3.6 if pin in RAISED else 2.6) * unit
            pen.ellipse([x - radius, y - radius, x + radius, y + radius],
                        fill=raised if pin in RAISED else rest)
    return image


def main() -> None:
    for theme, colours in THEMES.items():
        (FOLDER / theme).mkdir(exist_ok=True)
        draw(48, *colours).save(FOLDER / theme / "pinArrayTouch.png")
        draw(96, *colours).save(FOLDER / theme / "pinArrayTouch@2x.png")
    draw(48, *THEMES["light"]).save(FOLDER / "pinArrayTouch.png")


if __name__ == "__main__":
    main()
