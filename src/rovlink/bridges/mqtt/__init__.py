"""``rovlink mqtt``: one robot on an MQTT broker, and ``rovlink fleet``: every robot on it.

The pure parts — :mod:`broker` (the broker's address and credentials), :mod:`topics`,
:mod:`payloads` (what each topic carries), :mod:`commands` (the command topic's rules),
:mod:`outbox`, :mod:`fleet_view` and :mod:`broker_failure` (what went wrong with the broker, in
words) — need no MQTT library; :mod:`bridge` runs them on aiomqtt.
"""
