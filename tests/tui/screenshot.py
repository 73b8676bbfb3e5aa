"""The run screen's picture on the documentation's front page: ``python -m tests.tui.screenshot``
drives the experimenter's UI through a few trials on the simulated array (virtual time) and
saves the screen as SVG to docs/images/run-screen.svg."""

import asyncio
import tempfile
from pathlib import Path

from tests.tui.conftest import SIZE, make_app, settle, to_run_screen

IMAGE = Path(__file__).resolve().parents[2] / "docs" / "images" / "run-screen.svg"


async def draw(results: Path) -> None:
    app = make_app(results)
    async with app.run_test(size=SIZE) as pilot:
        await to_run_screen(pilot)
        await pilot.press("space")  # leave the instructions
        await settle(pilot)
        for answer in ("4", "1", "6", "10", "11", "13", "7"):  # practice and five trials answered
            await pilot.press("space")
            await settle(pilot)
            await pilot.press(answer, "enter")
            await settle(pilot)
        await pilot.press("space")
        await settle(pilot)
        app.save_screenshot(IMAGE.name, str(IMAGE.parent))


if __name__ == "__main__":
    with tempfile.TemporaryDirectory() as results:
        asyncio.run(draw(Path(results) / "results"))
    print(f"wrote {IMAGE}")
