"""Fault injection for links: ``fault://`` for the driver and tools, ``rovlink fault`` as a proxy.

Seeded bit errors, lost and duplicated bytes, and delays with jitter, in both directions,
counted. Wrap any URL the driver opens to see how a host behaves on a noisy tether.
"""

from rovlink.faults.injector import FaultCounters, FaultInjector
from rovlink.faults.port import FaultPort
from rovlink.faults.settings import FAULT_OPTIONS, FaultSettings, fault_url, parse_fault_url

__all__ = [
    "FAULT_OPTIONS",
    "FaultCounters",
    "FaultInjector",
    "FaultPort",
    "FaultSettings",
    "fault_url",
    "parse_fault_url",
]
