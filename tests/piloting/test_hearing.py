"""``--hear-other-lines``: the controller's debug output on, and on again after a reset."""

from __future__ import annotations

import pytest

from rovlink.cli import build_parser
from rovlink.piloting.hearing import hear_other_lines
from rovlink.protocol import Command
from tests.piloting.rig import Rig, until


async def test_debug_output_is_put_on_and_on_again_after_a_suspected_reset() -> None:
    rig = Rig.simulated()
    controller = rig.port.controller
    client = await rig.connect(checksum=True, timeout_s=0.25, retries=2)
    await hear_other_lines(client)
    assert controller.state().debug_enabled
    controller.reset()  # debug output off (P5); checksum off: the next query is suspected a reset
    (reply,) = await client.send(Command("qd"))
    assert reply.name == "qd"
    await until(lambda: controller.state().debug_enabled)
    assert [frame[:7] for frame in rig.frames()].count("#debug1") == 2  # (checksummed)
    await client.close()


@pytest.mark.parametrize("command", ["web", "monitor", "mavlink", "mqtt"])
def test_the_tools_that_show_the_lock_take_hear_other_lines_off_by_default(command: str) -> None:
    extra = ["--robot", "r1", "--broker", "mqtt://127.0.0.1"] if command == "mqtt" else []
    parser = build_parser(command, others=False)
    assert parser.parse_args([command, "sim://", "--hear-other-lines", *extra]).hear_other_lines
    assert not parser.parse_args([command, "sim://", *extra]).hear_other_lines
