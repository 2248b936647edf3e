"""The asyncio client's bound on queries on the wire: slots taken, waited for in order, and
never lost to a cancellation."""

from __future__ import annotations

import asyncio

from rovlink.aio.slots import InFlightSlots


async def _holder(slots: InFlightSlots, name: str, order: list[str]) -> None:
    await slots.take()
    order.append(name)


async def test_slots_are_handed_to_waiters_in_the_order_they_came() -> None:
    slots = InFlightSlots(1)
    await slots.take()
    assert slots.free == 0
    order: list[str] = []
    tasks = [asyncio.create_task(_holder(slots, name, order)) for name in "abc"]
    await asyncio.sleep(0)  # all three wait
    assert order == []
    for _ in tasks:
        slots.release()
        await asyncio.sleep(0)
        await asyncio.sleep(0)
    await asyncio.gather(*tasks)
    assert order == ["a", "b", "c"]
    assert slots.free == 0, "a slot handed over must not also count as free"
    slots.release()
    assert slots.free == 1


async def test_a_waiter_cancelled_while_waiting_takes_no_slot() -> None:
    slots = InFlightSlots(1)
    await slots.take()
    order: list[str] = []
    cancelled = asyncio.create_task(_holder(slots, "cancelled", order))
    waiting = asyncio.create_task(_holder(slots, "waiting", order))
    await asyncio.sleep(0)
    cancelled.cancel()
    await asyncio.sleep(0)
    slots.release()
    await waiting
    assert order == ["waiting"]
    assert cancelled.cancelled()
    slots.release()
    assert slots.free == 1


async def test_a_slot_handed_to_a_waiter_cancelled_before_it_ran_is_passed_on() -> None:
    slots = InFlightSlots(1)
    await slots.take()
    order: list[str] = []
    first = asyncio.create_task(_holder(slots, "first", order))
    second = asyncio.create_task(_holder(slots, "second", order))
    await asyncio.sleep(0)
    slots.release()  # handed to first ...
    first.cancel()  # ... which is cancelled before it runs
    await asyncio.gather(first, return_exceptions=True)
    await second
    assert order == ["second"]
    slots.release()
    assert slots.free == 1, "the slot of the cancelled waiter was lost"


async def test_a_cancelled_waiter_already_dropped_by_a_release_is_not_removed_twice() -> None:
    slots = InFlightSlots(1)
    await slots.take()
    waiter = asyncio.create_task(slots.take())
    await asyncio.sleep(0)
    waiter.cancel()  # its future is cancelled now, before the task runs ...
    slots.release()  # ... and the release skips it and frees the slot
    await asyncio.gather(waiter, return_exceptions=True)
    assert waiter.cancelled()
    assert slots.free == 1
