"""Reading a running textual app's screen as text, as a person would see it."""

from __future__ import annotations

import io
from typing import Any

from rich.console import Console
from textual.app import App
from textual.widgets import Digits, Static

from rovlink.monitor.app import Panel


def screen_text(app: App[Any]) -> str:
    """The whole screen as plain text (what ``export_screenshot`` draws, without the SVG)."""
    width, height = app.size
    console = Console(
        width=width,
        height=height,
        file=io.StringIO(),
        record=True,
        force_terminal=True,
        color_system=None,
        legacy_windows=False,
    )
    console.print(app.screen._compositor.render_update(full=True))
    return console.export_text()


def shown(app: App[Any], selector: str) -> str:
    """The text of one widget."""
    widget = app.query_one(selector)
    if isinstance(widget, Panel):
        return widget.text()
    if isinstance(widget, Digits):
        return widget.value
    assert isinstance(widget, Static)
    content = widget.content
    return content.plain if hasattr(content, "plain") else str(content)
