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
#: Twice viser's client-side GUI message throttle (50 ms, see `UI._type`).
VISER_THROTTLE_WAIT_MS = 120


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
        self.page.wait_for_timeout(VISER_THROTTLE_WAIT_MS)  # see `_type`

    @staticmethod
    def _type(box: Any, text: str) -> None:
        """Type like a person (select all, keys, Enter). Playwright's `fill` sets the value
        in one go, which Mantine's number input ignores when it equals the last value the
        input itself reported (even if the server changed the field since)."""
        box.click()
        for _ in range(3):
            box.press("Control+a")
            box.press_sequentially(text)
            # A server update that re-renders the field between the select-all and the keys
            # leaves the caret at the end and the keys are appended ("-70" + "70" = "-7070",
            # seen once in CI): check what the field holds and type it again if needed.
            if box.input_value() == text:
                break
        else:
            raise AssertionError(f"the field shows {box.input_value()!r} after typing {text!r}")
        box.press("Enter")
        # viser's client sends every GUI message through ONE 50 ms throttle that keeps only the
        # latest message: a click (or another field) within 50 ms of the last keystroke
        # replaces the field's final value, and the server sees a prefix ("P" for "P7, P8").
        # A person never types that fast; wait out the window as they would.
        box.page.wait_for_timeout(VISER_THROTTLE_WAIT_MS)

    def fill(self, label: str, value: Any) -> None:
        self._type(self.row(label).locator("input:not([type=hidden])").first, f"{value}")

    def fill_vec(self, label: str, values: tuple[float, ...]) -> None:
        boxes = self.row(label).locator("input")
        for i, v in enumerate(values):
            self._type(boxes.nth(i), f"{v:g}")

    def choose(self, label: str, option: str) -> None:
        self.row(label).locator("input").first.click()
        self.page.get_by_role("option", name=option, exact=True).click()
        self.page.wait_for_timeout(VISER_THROTTLE_WAIT_MS)  # see `_type`

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

    def wait_cell(self, text: str, timeout: float = WAIT_MS) -> Any:
        """A table cell (the page's lists are Markdown tables) with exactly this text."""
        loc = self.page.get_by_role("cell", name=text, exact=True).first
        loc.wait_for(state="visible", timeout=timeout)
        return loc

    def step(self, number: str) -> None:
        self.wait_text(f"Step {number} of 7")

    def wait_enabled(self, name: str, timeout: float = WAIT_MS, *, errors: int = 0) -> None:
        """Until the button is enabled; fails at once if an error notification beyond the
        first `errors` ones shows up (long waits must not hide a failure)."""
        handle = self.page.wait_for_function(
            """([n, k]) => {
                const errs = [...document.querySelectorAll('.mantine-Notification-root')]
                    .filter(e => e.innerText.includes('Could not do that'));
                if (errs.length > k) return 'ERROR: ' + errs[errs.length - 1].innerText;
                return [...document.querySelectorAll('button')].some(
                    b => b.textContent.trim() === n && !b.disabled) ? 'ok' : false;
            }""", arg=[name, errors], timeout=timeout, polling=250)
        result = handle.json_value()
        if result != "ok":
            raise AssertionError(f"waiting for {name!r}: the page shows {result}")

    def wait_no_errors(self, timeout: float = WAIT_MS) -> None:
        """Until no error notification is on screen and the toolbar shows no error."""
        self.page.wait_for_function(
            """() => ![...document.querySelectorAll('.mantine-Notification-root')]
                    .some(e => e.innerText.includes('Could not do that'))
                && !document.body.innerText.includes('Error:')""", timeout=timeout,
            polling=250)

    def errors(self) -> list[str]:
        """The error notifications on screen now."""
        loc = self.page.locator(".mantine-Notification-root", has_text="Could not do that")
        return [t.strip() for t in loc.all_inner_texts()]

    def shot(self, name: str) -> Path:
        self.shots.mkdir(parents=True, exist_ok=True)
        self._n += 1
        path = self.shots / f"{self._n:02d}-{name}.png"
        self.page.screenshot(path=str(path))
        return path
