"""Fixtures of the report's tests: one headless chromium per module (skipped, saying why,
where none starts)."""

import pytest
from report_browser import browser_driver


@pytest.fixture(scope="module")
def browser():
    yield from browser_driver()
