"""Both clients' command methods and the docs' method table come from one definition."""

from __future__ import annotations

from pathlib import Path

import pytest

from rovlink.client import method_table

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.parametrize(
    ("path", "render"),
    [
        ("src/rovlink/client/command_methods.py", method_table.render_blocking),
        ("src/rovlink/aio/command_methods.py", method_table.render_async),
    ],
)
def test_the_generated_methods_are_current(path: str, render: object) -> None:
    current = (ROOT / path).read_text()
    assert current == render(), (  # type: ignore[operator]
        f"{path} is out of date: run python -m rovlink.client.method_table"
    )


def test_the_docs_method_table_is_current() -> None:
    text = (ROOT / "docs/driver.md").read_text()
    assert text == method_table.docs_with_table(text), (
        "docs/driver.md's method table is out of date: run python -m rovlink.client.method_table"
    )


def test_ranges_in_the_docstrings_come_from_the_command_table() -> None:
    from rovlink.aio import AsyncClient
    from rovlink.client import Client

    for client in (Client, AsyncClient):
        assert "0–255" in (client.set_max_pwm.__doc__ or "")
        assert "-100…+100" in (client.set_vertical_thrust.__doc__ or "")
    assert "await rov.set_depth_zero(await rov.pressure_raw())" in (
        AsyncClient.set_depth_zero.__doc__ or ""
    )


def test_the_generator_writes_every_generated_file(tmp_path: Path) -> None:
    for path in ("src/rovlink/client", "src/rovlink/aio", "docs"):
        (tmp_path / path).mkdir(parents=True)
    (tmp_path / "docs/driver.md").write_text(
        f"before\n{method_table.DOCS_START}stale\n{method_table.DOCS_END}after\n"
    )
    method_table.main(tmp_path)
    assert (tmp_path / "src/rovlink/client/command_methods.py").read_text() == (
        method_table.render_blocking()
    )
    assert (tmp_path / "src/rovlink/aio/command_methods.py").read_text() == (
        method_table.render_async()
    )
    docs = (tmp_path / "docs/driver.md").read_text()
    assert "stale" not in docs
    assert docs.startswith("before\n")
    assert docs.endswith("after\n")
    assert "| `move(direction_deg, power_percent)` |" in docs
