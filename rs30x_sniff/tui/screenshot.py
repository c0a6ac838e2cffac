"""Render the monitor on a simulated bus as an SVG: ``python -m rs30x_sniff.tui.screenshot docs/monitor.svg``."""

from __future__ import annotations

import asyncio
import sys

from ..decode.decoder import DecodeOptions
from .app import make_app
from ..sources.feeds import ChunkSource

SIZE = (160, 48)


async def _shoot(path: str, scenario: str, seconds: float) -> None:
    from ..sim import run

    chunks = list(run(scenario, duration=seconds, seed=1))
    app = make_app(ChunkSource(f"simulator {scenario} ({seconds:g} s)", chunks), DecodeOptions(),
                   clock=lambda: 0.0, tick_interval=3600)
    async with app.run_test(size=SIZE) as pilot:
        while not app.done:
            await pilot.pause(0.05)
        await pilot.pause()
        # Show the first packet the linter flagged, with its field picked out in the hex dump.
        await pilot.press("home", "n", "tab", "down", "down", "down")
        await pilot.pause()
        app.save_screenshot(path)


def main(argv: list[str] | None = None) -> int:
    args = sys.argv[1:] if argv is None else argv
    path = args[0] if args else "docs/monitor.svg"
    scenario = args[1] if len(args) > 1 else "bad-checksum"
    asyncio.run(_shoot(path, scenario, 2.0))
    print(path)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
