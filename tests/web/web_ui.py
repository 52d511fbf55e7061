"""Driving the cellteach page like an operator: find controls by their visible labels."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

CHROMIUM = "/usr/bin/chromium"
CHROMIUM_ARGS = ["--no-sandbox", "--disable-gpu", "--use-gl=swiftshader",
                 "--enable-unsafe-swiftshader", "--disable-background-networking",
                 "--disable-component-update", "--disable-sync", "--no-first-run"]
#: Generous bound for anything the page must show (a failure, not a timing assertion).
WAIT_MS = 60_000


class UI:
    def __init__(self, page: Any, shots: Path):
        self.page = page
        self.shots = shots
        self._n = 0

    def open(self, url: str) -> None:
        self.page.goto(url)
        self.wait_text(re.compile(r"Step \d+(\.\d+)? of 7"))

    # ------------------------------------------------------------------ finding
    def row(self, label: str) -> Any:
        """The control row whose label is `label` (number, vector, text, dropdown, ...)."""
        return self.page.locator(
            f"xpath=//label[normalize-space()='{label}']"
            "/ancestor::div[contains(@class,'mantine-Flex-root')][1]")

    def button(self, name: str) -> Any:
        return self.page.get_by_role("button", name=name, exact=True)

    # ------------------------------------------------------------------ acting
    def click(self, name: str) -> None:
        self.button(name).click()

    def fill(self, label: str, value: Any) -> None:
        box = self.row(label).locator("input:not([type=hidden])").first
        box.fill(str(value))
        box.press("Enter")

    def fill_vec(self, label: str, values: tuple[float, ...]) -> None:
        boxes = self.row(label).locator("input")
        for i, v in enumerate(values):
            boxes.nth(i).fill(f"{v:g}")
            boxes.nth(i).press("Enter")

    def choose(self, label: str, option: str) -> None:
        self.row(label).locator("input").first.click()
        self.page.get_by_role("option", name=option, exact=True).click()

    def expand(self, folder: str, probe: Any) -> None:
        """Open a collapsed folder so that `probe` (a locator inside it) can be used."""
        if not probe.is_visible():
            self.page.get_by_text(folder, exact=True).first.click()
            probe.wait_for(state="visible")

    def upload(self, button: str, path: Path) -> None:
        with self.page.expect_file_chooser() as chooser:
            self.click(button)
        chooser.value.set_files(str(path))

    def download(self, button: str) -> tuple[str, bytes]:
        with self.page.expect_download(timeout=WAIT_MS) as info:
            self.click(button)
        d = info.value
        return d.suggested_filename, Path(d.path()).read_bytes()

    # ------------------------------------------------------------------ waiting
    def wait_text(self, text: str | re.Pattern, timeout: float = WAIT_MS) -> Any:
        loc = self.page.get_by_text(text).first
        loc.wait_for(state="visible", timeout=timeout)
        return loc

    def step(self, number: str) -> None:
        self.wait_text(f"Step {number} of 7")

    def wait_enabled(self, name: str, timeout: float = WAIT_MS) -> None:
        self.page.wait_for_function(
            "([n]) => [...document.querySelectorAll('button')].some("
            "b => b.textContent.trim() === n && !b.disabled)", arg=[name], timeout=timeout)

    def shot(self, name: str) -> Path:
        self.shots.mkdir(parents=True, exist_ok=True)
        self._n += 1
        path = self.shots / f"{self._n:02d}-{name}.png"
        self.page.screenshot(path=str(path))
        return path
