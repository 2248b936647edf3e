"""Ending a bridge's tasks for sure, Python 3.10 included.

On Python 3.10, ``asyncio.wait_for`` swallows a cancellation that comes just as what it waits
for completes (bpo-37658). Libraries wait so for every acknowledgement (aiomqtt for each QoS 1
PUBACK): a task cancelled as one arrives runs on, and a bridge that waited for it to end never
ended. A task still running some time after its cancellation is cancelled again.
"""

from __future__ import annotations

import asyncio
from collections.abc import Iterable
from typing import Any

__all__ = ["cancel_and_wait"]


async def cancel_and_wait(tasks: Iterable[asyncio.Future[Any]], *, recancel_after_s: float) -> None:
    """Cancel ``tasks`` and wait until each has ended; one still running ``recancel_after_s``
    after a cancellation (which it swallowed, or is still ending on) is cancelled again. Their
    outcomes are retrieved (nothing is said about an exception never retrieved).

    Example::

        await cancel_and_wait([poller, publisher], recancel_after_s=1.0)
    """
    tasks = list(tasks)
    pending = {task for task in tasks if not task.done()}
    while pending:
        for task in pending:
            task.cancel()
        _, pending = await asyncio.wait(pending, timeout=recancel_after_s)
    for task in tasks:
        if not task.cancelled():
            task.exception()
