"""The fault injector: seeded, counted, rates as asked, independent of chunking."""

from __future__ import annotations

import random

import pytest

from rovlink.faults import FaultInjector, FaultSettings, fault_url, parse_fault_url


def _damage(seed: int, data: bytes, chunk: int, **rates: float) -> tuple[bytes, FaultInjector]:
    injector = FaultInjector(rng=random.Random(seed), **rates)
    out = b"".join(injector.apply(data[i : i + chunk]) for i in range(0, len(data), chunk))
    return out, injector


def test_same_seed_same_damage_however_chunked() -> None:
    data = bytes(range(256)) * 200
    whole, _ = _damage(5, data, len(data), ber=1e-3, drop=1e-3, dup=1e-3)
    pieces, _ = _damage(5, data, 7, ber=1e-3, drop=1e-3, dup=1e-3)
    other, _ = _damage(6, data, len(data), ber=1e-3, drop=1e-3, dup=1e-3)
    assert whole == pieces
    assert whole != other


def test_bit_error_rate_and_counters() -> None:
    data = bytes(100_000)
    out, injector = _damage(1, data, 1000, ber=1e-3, drop=0.0, dup=0.0)
    flipped_bits = sum(bin(byte).count("1") for byte in out)
    assert flipped_bits == injector.counters.bits_flipped
    assert 700 <= flipped_bits <= 900  # 800 expected; ±3.5 sigma
    assert injector.counters.bytes_in == len(data)


def test_drops_and_duplicates_change_the_length_by_their_counts() -> None:
    data = b"#qd!" * 10_000
    out, injector = _damage(2, data, 64, ber=0.0, drop=0.01, dup=0.005)
    counters = injector.counters
    assert len(out) == len(data) - counters.bytes_dropped + counters.bytes_duplicated
    assert 300 <= counters.bytes_dropped <= 500
    assert 130 <= counters.bytes_duplicated <= 270


def test_no_faults_leave_bytes_alone() -> None:
    out, injector = _damage(3, b"#qd!" * 100, 5, ber=0.0, drop=0.0, dup=0.0)
    assert out == b"#qd!" * 100
    assert injector.counters.bits_flipped == 0


def test_url_round_trip_and_errors() -> None:
    settings = FaultSettings(ber=1e-3, drop=0.01, dup=0.005, delay_ms=5, jitter_ms=2, seed=1)
    url = fault_url("sim://?seed=1&realtime=0", settings)
    assert parse_fault_url(url) == ("sim://?seed=1&realtime=0", settings)
    with pytest.raises(ValueError, match=r"unknown fault option 'realtime'.*percent-encode"):
        parse_fault_url("fault://?inner=sim://?seed=1&realtime=0")
    with pytest.raises(ValueError, match=r"ber must be in 0–0\.5, got 2\.0"):
        parse_fault_url("fault://?inner=sim://&ber=2")
    with pytest.raises(ValueError, match="jitter_ms must be in 0–1"):
        parse_fault_url("fault://?inner=sim://&delay_ms=1&jitter_ms=2")
    with pytest.raises(ValueError, match="seed must be an integer"):
        parse_fault_url("fault://?inner=sim://&seed=x")


def test_url_round_trip_keeps_every_digit() -> None:
    # Before, the URL kept 6 significant digits: ber 0.0012345678 came back as 0.00123457.
    settings = FaultSettings(ber=0.0012345678, delay_ms=1234.5678, jitter_ms=0.1234567, seed=3)
    assert parse_fault_url(fault_url("sim://", settings)) == ("sim://", settings)
    assert fault_url("sim://", FaultSettings(ber=1e-3)) == "fault://?inner=sim%3A%2F%2F&ber=0.001"
