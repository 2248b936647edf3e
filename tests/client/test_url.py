"""Connection URLs are parsed and checked before anything is opened."""

from __future__ import annotations

import pytest

from rovlink.client.url import DEFAULT_BAUDRATE, Scheme, parse_url
from rovlink.sim.url import SimOptions, parse_sim_url


@pytest.mark.parametrize(
    ("url", "scheme", "target", "baudrate"),
    [
        ("/dev/ttyUSB0", Scheme.SERIAL, "/dev/ttyUSB0", DEFAULT_BAUDRATE),
        ("/dev/ttyUSB0?baudrate=9600", Scheme.SERIAL, "/dev/ttyUSB0", 9600),
        ("/dev/pts/7", Scheme.SERIAL, "/dev/pts/7", DEFAULT_BAUDRATE),
        ("loop://", Scheme.SERIAL, "loop://", DEFAULT_BAUDRATE),
        ("rfc2217://host:7000?baudrate=57600", Scheme.SERIAL, "rfc2217://host:7000", 57600),
        ("spy://COM3?file=log.txt", Scheme.SERIAL, "spy://COM3?file=log.txt", DEFAULT_BAUDRATE),
        # An option without a value (pyserial's flags) stays a bare name.
        (
            "rfc2217://host:7000?ign_set_control&baudrate=9600",
            Scheme.SERIAL,
            "rfc2217://host:7000?ign_set_control",
            9600,
        ),
        ("spy://COM3?file=log.txt&raw", Scheme.SERIAL, "spy://COM3?file=log.txt&raw", 115200),
        ("socket://localhost:5760", Scheme.TCP, "localhost:5760", DEFAULT_BAUDRATE),
        # pyserial's own socket options go to pyserial's handler.
        (
            "socket://localhost:5760?logging=debug",
            Scheme.SERIAL,
            "socket://localhost:5760?logging=debug",
            DEFAULT_BAUDRATE,
        ),
    ],
)
def test_serial_and_tcp_urls(url: str, scheme: Scheme, target: str, baudrate: int) -> None:
    endpoint = parse_url(url)
    assert (endpoint.scheme, endpoint.target, endpoint.baudrate) == (scheme, target, baudrate)


@pytest.mark.parametrize("url", ["nosuch://", "soket://localhost:5760", "sim2://?seed=1"])
def test_an_unknown_scheme_is_refused_naming_it_and_the_known_ones(url: str) -> None:
    # Before, it went to pyserial, and failed as a port that could not be opened ("protocol
    # 'nosuch' not known"); `rovlink send nosuch:// qd` exited 1 with "cannot open".
    scheme = url.partition("://")[0]
    with pytest.raises(ValueError, match="unknown URL scheme") as raised:
        parse_url(url)
    message = str(raised.value)
    assert f"unknown URL scheme {scheme}://" in message
    for known in ("socket://", "loop://", "rfc2217://", "spy://", "sim://", "fault://"):
        assert known in message
    assert "/dev/ttyUSB0" in message


@pytest.mark.parametrize(
    "url", ["LOOP://", "spy://loop://", "hwgrep://0403", "alt://loop://?class=Serial", "COM3"]
)
def test_every_scheme_pyserial_opens_is_still_taken(url: str) -> None:
    assert parse_url(url).scheme is Scheme.SERIAL


def test_tcp_host_and_port() -> None:
    endpoint = parse_url("socket://[::1]:5760")
    assert (endpoint.host, endpoint.port) == ("::1", 5760)


def test_baudrate_argument_and_url_must_agree() -> None:
    assert parse_url("/dev/ttyS0", baudrate=9600).baudrate == 9600
    assert parse_url("/dev/ttyS0?baudrate=9600", baudrate=9600).baudrate == 9600
    with pytest.raises(ValueError, match="disagrees"):
        parse_url("/dev/ttyS0?baudrate=9600", baudrate=115200)


def test_sim_urls_go_to_the_registered_handler_which_reads_the_options() -> None:
    url = "sim://?leak_at=5&seed=1&realtime=0&config=robot.toml"
    endpoint = parse_url(url)
    assert endpoint.scheme is Scheme.REGISTERED
    assert (endpoint.handler, endpoint.target) == ("sim", url)
    assert parse_sim_url(url) == SimOptions(
        seed=1, leak_at_s=5.0, config="robot.toml", realtime=False
    )
    assert parse_sim_url("sim://") == SimOptions()


def test_a_registered_scheme_in_upper_case_is_refused_naming_the_scheme() -> None:
    # Before, SIM:// went to pyserial, which said "protocol 'sim' not known" of rovlink's own.
    with pytest.raises(
        ValueError, match=r"'SIM://\?seed=1': write the scheme in lower case: sim://"
    ):
        parse_url("SIM://?seed=1")


def test_a_sim_option_repeated_with_the_same_value_is_taken() -> None:
    # As ?baudrate= given twice with one value: only a contradiction is refused.
    assert parse_sim_url("sim://?seed=1&seed=1") == SimOptions(seed=1)


@pytest.mark.parametrize(
    ("url", "message"),
    [
        ("", "non-empty"),
        ("sim://?speed=2", "unknown sim option 'speed'"),
        ("sim://?seed=x", "seed must be an integer"),
        ("sim://?leak_at=-1", "leak_at must be a non-negative"),
        ("sim://?leak_at=inf", "leak_at must be a non-negative number of seconds"),
        ("sim://?realtime=maybe", "realtime must be 1 or 0"),
        ("sim://host", "no host or path"),
        ("sim://?seed=1&leak_at=5&seed=2", "sim option 'seed' given twice with different values"),
        ("/dev/ttyUSB0?baudrate=fast", "baudrate must be an integer in 1–12000000"),
        ("/dev/ttyUSB0?baudrate=99999999999999999999", "baudrate must be an integer in 1–"),
        ("/dev/ttyUSB0?baudrate=0", "baudrate must be an integer in 1–"),
        ("/dev/ttyUSB0?baudrate", "baudrate must be an integer in 1–"),
        ("loop://?&logging=debug", "malformed query"),
        ("/dev/ttyUSB0?parity=E", r"only \?baudrate=, not parity"),
        ("socket://localhost", "HOST:PORT"),
        ("socket://localhost:99999", "HOST:PORT"),
    ],
)
def test_bad_urls_say_what_is_wrong(url: str, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        parse_url(url)


@pytest.mark.parametrize("url", ["sim://", "/dev/ttyUSB0", "socket://localhost:5760"])
@pytest.mark.parametrize(
    ("baudrate", "error"),
    [
        (0, ValueError),
        (-9600, ValueError),
        ("9600", TypeError),
        (9600.0, TypeError),
        (True, TypeError),
    ],
)
def test_a_bad_baudrate_argument_is_refused_whatever_the_url(
    url: str, baudrate: object, error: type[Exception]
) -> None:
    # (Before, sim:// took any baudrate=, and a program found its mistake on the robot's port.)
    with pytest.raises(error, match=r"baudrate must be an integer in 1–12000000, got "):
        parse_url(url, baudrate)  # type: ignore[arg-type]


@pytest.mark.parametrize(("url", "error"), [(123, TypeError), (None, TypeError), (" ", ValueError)])
def test_a_url_that_is_no_text_is_a_type_error(url: object, error: type[Exception]) -> None:
    with pytest.raises(error, match=r"connection URL must be a non-empty string, got "):
        parse_url(url)  # type: ignore[arg-type]
