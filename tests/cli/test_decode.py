"""``rovlink decode``: JSON lines per event, --checksum, --algorithm, --stats."""

from __future__ import annotations

import json
from pathlib import Path

from typer.testing import CliRunner

from rovlink.cli import app

runner = CliRunner()


def _lines(output: str) -> list[dict[str, object]]:
    return [json.loads(line) for line in output.splitlines()]


def test_decode_prints_one_json_object_per_event(tmp_path: Path) -> None:
    capture = tmp_path / "capture.bin"
    capture.write_bytes(
        b"boot ok\r\n#qd!$qd.123!$qro.-1!$qpi.-.7!#mvs.+100!#th.270.25!$q.l.1!#mvpdd.5!"
        b"#h+!#debug1!#crcon!#dive!#mgmp.300!#qd"
    )
    result = runner.invoke(app, ["decode", str(capture)])
    assert result.exit_code == 0, result.output
    events = _lines(result.output)
    assert events[0] == {"event": "text", "text": "boot ok"}
    frames = [(e["kind"], e["name"], e["values"]) for e in events if e["event"] == "frame"]
    assert frames == [
        ("command", "qd", []), ("response", "qd", [123]), ("response", "qro", [-1]),
        ("response", "qpi", [-7]), ("command", "mvs", [100]), ("command", "th", [270, 25]),
        ("response", "q.l", [1]), ("command", "mvpidd", [5]), ("command", "h+", []),
        ("command", "debug1", []), ("command", "crcon", []),
    ]
    assert events[1]["raw"] == "#qd!"
    errors = [(e["reason"], e["raw"]) for e in events if e["event"] == "error"]
    # After #crcon! the decoder is in checksum mode: the next frames lack checksums.
    assert errors == [("checksum", "#dive!"), ("checksum", "#mgmp.300!"), ("truncated", "#qd")]


def test_decode_reads_standard_input_and_checksum_options() -> None:
    result = runner.invoke(app, ["decode", "--checksum"], input=b"#qd8C!#qd!")
    assert result.exit_code == 0, result.output
    assert [e["event"] for e in _lines(result.output)] == ["frame", "error"]
    result = runner.invoke(
        app, ["decode", "--checksum", "--algorithm", "xor"], input=b"#qd%02X!" % (0x71 ^ 0x64)
    )
    assert _lines(result.output)[0]["name"] == "qd"


def test_decode_rejects_an_unknown_algorithm() -> None:
    result = runner.invoke(app, ["decode", "--algorithm", "md5"], input=b"")
    assert result.exit_code != 0
    assert "md5" in result.output


def test_decode_stats_counts_events_reasons_and_names() -> None:
    result = runner.invoke(app, ["decode", "--stats"], input=b"#qd!$qd.1!$qd.2!#zz!#mgmp.999!x\n")
    assert result.exit_code == 0, result.output
    (summary,) = _lines(result.output)
    assert summary == {
        "events": {"error": 2, "frame": 3, "text": 1},
        "reasons": {"range": 1, "unknown": 1},
        "names": {"command": {"qd": 1}, "response": {"qd": 2}},
    }

