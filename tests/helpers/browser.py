"""Headless Chromium for the browser tests: Debian's ``chromium``, WebGL on SwiftShader; tests skip without it."""

from __future__ import annotations

from pathlib import Path

import pytest

CHROMIUM = Path("/usr/bin/chromium")
# WebGL in headless Chromium without a GPU: ANGLE on SwiftShader (software Vulkan).
CHROMIUM_FLAGS = ["--headless", "--no-sandbox", "--use-angle=swiftshader", "--enable-unsafe-swiftshader",
                  "--disable-background-networking", "--mute-audio"]


def require_chromium() -> None:
    """Skip the calling test when Chromium is absent."""
    if not CHROMIUM.exists():
        pytest.skip(f"{CHROMIUM} is absent (install Debian's `chromium` package to run the browser test)")
