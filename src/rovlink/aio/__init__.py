"""The host driver for asyncio: ``async with rovlink.aio.connect(url) as rov``.

The same URLs, options and method names as :func:`rovlink.connect`, as coroutines; several
queries may be in flight at once, and ``rov.telemetry(rate_hz)`` streams sensor readings.

Example::

    import asyncio
    import rovlink.aio

    async def main() -> None:
        async with rovlink.aio.connect("sim://") as rov:
            await rov.start()
            await rov.hold_depth(100)
            async for reading in rov.telemetry(5):
                print(reading.depth_cm)

    asyncio.run(main())
"""

from rovlink.aio.client import DEFAULT_MAX_IN_FLIGHT, AsyncClient, connect
from rovlink.client import (
    ClientError,
    ConnectError,
    ConnectionLostError,
    InvalidArgumentError,
    QueryTimeoutError,
    Sensors,
    SupersededByStopError,
)

__all__ = [
    "DEFAULT_MAX_IN_FLIGHT",
    "AsyncClient",
    "ClientError",
    "ConnectError",
    "ConnectionLostError",
    "InvalidArgumentError",
    "QueryTimeoutError",
    "Sensors",
    "SupersededByStopError",
    "connect",
]
