"""One version source: the installed distribution's version is the package's ``__version__``."""

from __future__ import annotations

import importlib.metadata
import importlib.util
import platform
import sys
from pathlib import Path
from types import ModuleType

import pytest

import rovlink

if sys.version_info >= (3, 11):
    import tomllib
else:
    import tomli as tomllib

ROOT = Path(__file__).resolve().parents[1]


def test_the_package_and_its_metadata_agree_on_the_version() -> None:
    assert rovlink.__version__ == importlib.metadata.version("rovlink")


def _build_hook(monkeypatch: pytest.MonkeyPatch) -> ModuleType:
    """hatch_build.py, with hatchling's interface (a build dependency, not a test one) stood in."""
    interface = ModuleType("hatchling.metadata.plugin.interface")
    interface.MetadataHookInterface = object  # type: ignore[attr-defined]
    monkeypatch.setitem(sys.modules, "hatchling.metadata.plugin.interface", interface)
    spec = importlib.util.spec_from_file_location("hatch_build", ROOT / "hatch_build.py")
    assert spec is not None
    assert spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.mark.parametrize(("version", "refused"), [("3.9.18", True), ("3.10.0", False)])
def test_the_build_stops_at_once_on_a_python_too_old(
    monkeypatch: pytest.MonkeyPatch, version: str, refused: bool
) -> None:
    # The README says pip stops at once there. Before, the pip of Python 3.9's venv (23.0)
    # resolved and downloaded every dependency for minutes before it looked at requires-python.
    hook = _build_hook(monkeypatch)
    project = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["project"]
    assert (
        tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["tool"]["hatch"][
            "metadata"
        ]["hooks"]["custom"]
        == {}
    )
    monkeypatch.setattr(platform, "python_version", lambda: version)
    if not refused:
        hook.RefuseUnsupportedPython.update(None, project)
        return
    with pytest.raises(SystemExit) as stopped:
        hook.RefuseUnsupportedPython.update(None, project)
    assert str(stopped.value) == (
        f"rovlink needs Python {project['requires-python']} (this is Python {version}): "
        "see README.md"
    )
