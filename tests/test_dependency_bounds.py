"""The extras' lower bounds are releases the code works with.

pip keeps an older release that a bound admits (a lock file, a shared or system environment),
so a bound below what the code uses fails only in real use, mid-task: each release named here
was tried (the extra's commands, and its tests, with every direct dependency at its lowest).
"""

from __future__ import annotations

import sys
from pathlib import Path

import pytest
from packaging.requirements import Requirement
from packaging.version import Version

if sys.version_info >= (3, 11):
    import tomllib
else:
    import tomli as tomllib

ROOT = Path(__file__).resolve().parents[1]

#: Each library's oldest release that rovlink works with, and what the releases before it lack.
OLDEST_WORKING = {
    "mcap": ("1.5", "Writer.flush, which the recorder calls every second"),
    "pymavlink": (
        "2.4.49",
        "MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_C_CAST, in the bridge's AUTOPILOT_VERSION",
    ),
    "textual": ("2.0", "the text-wrap and text-overflow CSS rules of the monitor's sheet"),
    "uvicorn": (
        "0.52.1",
        'ws="websockets-sansio" (0.35), and its waiting on a full socket (0.52.1): before, a '
        "pilot's page that stopped reading kept control, its messages buffered without limit",
    ),
    "aiomqtt": (
        "2.5.1",
        "importing on Python 3.10 (before 2.5) and connecting to an mqtts:// broker (2.5.0)",
    ),
}


def _lower_bounds() -> dict[str, Version]:
    """The lowest release any extra admits, by library name."""
    extras = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["project"][
        "optional-dependencies"
    ]
    bounds: dict[str, Version] = {}
    for requirements in extras.values():
        for text in requirements:
            requirement = Requirement(text)
            for specifier in requirement.specifier:
                if specifier.operator in {">=", "==", "~="}:
                    name, version = requirement.name.lower(), Version(specifier.version)
                    bounds[name] = min(bounds.get(name, version), version)
    return bounds


@pytest.mark.parametrize("library", sorted(OLDEST_WORKING))
def test_no_extra_admits_a_release_the_code_fails_with(library: str) -> None:
    # Before: mcap>=1.2 (a recording failed within its first second), textual>=0.80 (the monitor
    # refused its own style sheet), uvicorn>=0.30 (rovlink web: a KeyError traceback at start;
    # to 0.52.0, a pilot's page that stopped reading was never closed and kept control),
    # pymavlink>=2.4.40 (a ground station's AUTOPILOT_VERSION request: no reply, no ack),
    # aiomqtt>=2.3 (on Python 3.10, rovlink mqtt said "needs aiomqtt" with aiomqtt installed;
    # 2.5.0 raised a ValueError for every mqtts:// broker).
    oldest, lacking = OLDEST_WORKING[library]
    bound = _lower_bounds().get(library)
    assert bound is not None, f"no extra names {library} with a lower bound"
    assert bound >= Version(oldest), f"{library}>={bound} admits releases without {lacking}"
