"""The whole autotune: relay experiment, rule, gains, verification; ``#stop!`` whatever happens."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from rovlink.logs import get_logger
from rovlink.tuning.plant import Plant
from rovlink.tuning.relay import RelayResult, RelaySettings, run_relay
from rovlink.tuning.rules import GainScales, PhysicalGains, ProtocolGains, Rule, physical_gains
from rovlink.tuning.verify import StepResult, StepSettings, run_step

__all__ = ["TuneResult", "autotune"]

logger = get_logger(__name__)


@dataclass
class TuneResult:
    """What the autotune found and how the gains did."""

    relay: RelayResult
    rule: Rule
    physical: PhysicalGains
    gains: ProtocolGains
    step: StepResult | None


def autotune(
    plant: Plant,
    relay_settings: RelaySettings,
    rule: Rule,
    scales: GainScales,
    step_settings: StepSettings | None,
    *,
    progress: Callable[[str], None] | None = None,
) -> TuneResult:
    """Unlock, run the relay in direct mode, compute the gains, verify them with a step
    (unless ``step_settings`` is None), and lock the motors again, whatever happens.

    ``progress`` is told, in a line each, what starts and what the relay found: the whole
    takes minutes, with the motors running.
    """
    client = plant.client
    tell = progress or (lambda _line: None)
    try:
        plant.sample(enforce_min=False)  # a leak or a dead link stops us before any motion
        plant.send(client.start)
        plant.send(lambda: client.set_direct_mode(True))
        tell(
            f"motors unlocked: relay of ±{relay_settings.amplitude_percent:g} % vertical thrust "
            f"around {relay_settings.target_cm:g} cm (up to {relay_settings.timeout_s:g} s)"
        )
        relay = run_relay(plant, relay_settings)
        plant.vertical_thrust(0)
        physical = physical_gains(relay.ultimate_gain, relay.ultimate_period_s, rule, scales.max_kp)
        gains = physical.to_protocol(scales)
        logger.info(
            "relay: Ku %.3f %%/cm, Tu %.2f s, amplitude %.1f cm, trim %.1f %%; gains %s",
            relay.ultimate_gain,
            relay.ultimate_period_s,
            relay.amplitude_cm,
            relay.bias_percent,
            gains,
        )
        tell(
            f"relay done: Ku {relay.ultimate_gain:.3f} %/cm, Tu {relay.ultimate_period_s:.2f} s "
            f"-> mvpdp {gains.kp}, mvpdi {gains.ki}, mvpidd {gains.kd} ({rule.name})"
        )
        step = None
        if step_settings is not None:
            tell(
                f"verifying: holding {step_settings.from_cm} cm for {step_settings.hold_s:g} s, "
                f"then a step to {step_settings.to_cm} cm watched for {step_settings.watch_s:g} s"
            )
            step = run_step(plant, gains, step_settings)
        return TuneResult(relay, rule, physical, gains, step)
    finally:
        plant.stop()
