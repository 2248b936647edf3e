"""``rovlink decode``: JSON lines per event, --checksum, --algorithm, --stats."""

from __future__ import annotations

import io
import json
import sys
from pathlib import Path

import pytest

from rovlink.cli import main
from rovlink.protocol.frames import Reason
from tests.cli.conftest import RunCli


def _lines(output: str) -> list[dict[str, object]]:
    return [json.loads(line) for line in output.splitlines()]


def test_decode_prints_one_json_object_per_event(tmp_path: Path, run_cli: RunCli) -> None:
    capture = tmp_path / "capture.bin"
    capture.write_bytes(
        b"boot ok\r\n#qd!$qd.123!$qro.-1!$qpi.-.7!#mvs.+100!#th.270.25!$q.l.1!#mvpdd.5!"
        b"#h+!#debug1!#crcon!#dive!#mgmp.300!#qd"
    )
    result = run_cli("decode", str(capture))
    assert result.status == 0, result.err
    events = _lines(result.out)
    assert events[0] == {"event": "text", "text": "boot ok"}
    frames = [(e["kind"], e["name"], e["values"]) for e in events if e["event"] == "frame"]
    assert frames == [
        ("command", "qd", []),
        ("response", "qd", [123]),
        ("response", "qro", [-1]),
        ("response", "qpi", [-7]),
        ("command", "mvs", [100]),
        ("command", "th", [270, 25]),
        ("response", "q.l", [1]),
        ("command", "mvpidd", [5]),
        ("command", "h+", []),
        ("command", "debug1", []),
        ("command", "crcon", []),
    ]
    assert events[1]["raw"] == "#qd!"
    errors = [(e["reason"], e["raw"]) for e in events if e["event"] == "error"]
    # After #crcon! the decoder is in checksum mode: the next frames lack checksums.
    assert errors == [("checksum", "#dive!"), ("checksum", "#mgmp.300!"), ("truncated", "#qd")]


@pytest.mark.parametrize("file", [[], ["-"]])
def test_decode_reads_standard_input_and_checksum_options(run_cli: RunCli, file: list[str]) -> None:
    result = run_cli("decode", "--checksum", *file, stdin=b"#qd8C!#qd!")
    assert result.status == 0, result.err
    assert [e["event"] for e in _lines(result.out)] == ["frame", "error"]
    result = run_cli(
        "decode", "--checksum", "--algorithm", "xor", *file, stdin=b"#qd%02X!" % (0x71 ^ 0x64)
    )
    assert _lines(result.out)[0]["name"] == "qd"
    result = run_cli("decode", "--no-checksum", *file, stdin=b"#qd!")
    assert _lines(result.out)[0]["name"] == "qd"


def test_decode_rejects_an_unknown_algorithm_naming_the_known_ones(run_cli: RunCli) -> None:
    result = run_cli("decode", "--algorithm", "md5")
    assert result.status == 2
    assert "unknown checksum algorithm 'md5'; known: crc8, sum8, xor" in result.err


def test_unreadable_files_are_one_line_errors(run_cli: RunCli, tmp_path: Path) -> None:
    missing = tmp_path / "missing.bin"
    result = run_cli("decode", str(missing))
    assert (result.status, result.out) == (1, "")
    assert result.err == f"rovlink decode: cannot read {missing}: No such file or directory\n"
    result = run_cli("decode", str(tmp_path))
    assert result.status == 1
    assert result.err.count("\n") == 1
    assert str(tmp_path) in result.err


def test_decode_stats_counts_events_reasons_and_names(run_cli: RunCli) -> None:
    result = run_cli("decode", "--stats", stdin=b"#qd!$qd.1!$qd.2!#zz!#mgmp.999!x\n")
    assert result.status == 0, result.err
    (summary,) = _lines(result.out)
    assert summary == {
        "events": {"error": 2, "frame": 3, "text": 1},
        "reasons": {"range": 1, "unknown": 1},
        "names": {"command": {"qd": 1}, "response": {"qd": 2}},
    }


def test_decode_escapes_del_and_c1_controls_as_json_does_c0(run_cli: RunCli) -> None:
    # Line noise with DEL, an ESC, and a C1 CSI (U+009B, which some terminals obey): none
    # reaches the terminal raw, and the line reads back exactly.
    result = run_cli("decode", stdin=b"a\x7fb\x1b[2Jc\xc2\x9b31md\r\n#q\x9bd!")
    assert result.status == 0, result.err
    assert all(ch.isprintable() for ch in result.out.replace("\n", ""))
    assert "\\u007f" in result.out
    assert "\\u009b" in result.out
    events = _lines(result.out)
    assert events[0] == {"event": "text", "text": "a\x7fb\x1b[2Jc\x9b31md"}
    assert [(e["event"], e.get("raw")) for e in events[1:]] == [("error", "#q"), ("text", None)]


def test_the_json_schema_in_the_docs_names_every_event_s_keys_and_every_reason(
    run_cli: RunCli,
) -> None:
    # docs/tools.md describes the keys of each event; the decoder's output must have them.
    docs = (Path(__file__).resolve().parents[2] / "docs" / "tools.md").read_text("utf-8")
    rows = {
        row.split("|")[1].strip().strip('`"'): row.split("|")[2]
        for row in docs.splitlines()
        if row.startswith('| `"') and row.count("|") == 3
    }
    result = run_cli("decode", "-", stdin=b"boot\n#qd!$qd.5!#zz!")
    for line in result.out.splitlines():
        event = json.loads(line)
        for key in set(event) - {"event"}:
            assert f'`"{key}"`' in rows[str(event["event"])], (event["event"], key)
    assert {reason.value for reason in Reason} == {
        word.strip('`"') for word in rows["error"].split("(")[1].split(")")[0].split(", ")
    }


@pytest.mark.parametrize("encoding", ["ascii", "latin-1"])
@pytest.mark.parametrize("options", [[], ["--stats"]])
def test_decode_writes_noise_to_an_output_that_is_not_utf_8(
    run_cli: RunCli, monkeypatch: pytest.MonkeyPatch, encoding: str, options: list[str]
) -> None:
    # Line noise that is not UTF-8 is text with U+FFFD, and bytes in a bad frame are Latin-1
    # characters: an ASCII or Latin-1 terminal gets them as JSON escapes, not a traceback.
    output = io.BytesIO()
    monkeypatch.setattr(sys, "stdout", io.TextIOWrapper(output, encoding=encoding))
    result = run_cli("decode", *options, stdin=b"ab\xffcd\r\n#q\xe9d!#zz\x80!")
    assert result.status == 0, result.err
    sys.stdout.flush()
    lines = [json.loads(line) for line in output.getvalue().decode(encoding).splitlines()]
    if options:
        assert lines[0]["events"] == {"error": 2, "text": 3}
    else:
        assert lines[0] == {"event": "text", "text": "ab\ufffdcd"}
        assert lines[1]["raw"] == "#q"
        assert lines[3]["raw"] == "#zz"


def test_decode_of_a_closed_standard_input_is_a_one_line_error(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    # `rovlink decode <&-`: Python has no sys.stdin at all.
    monkeypatch.setattr(sys, "stdin", None)
    assert main(["decode"]) == 1
    captured = capsys.readouterr()
    assert (captured.out, captured.err) == (
        "",
        "rovlink decode: cannot read standard input: closed\n",
    )
