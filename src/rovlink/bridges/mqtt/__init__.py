"""``rovlink mqtt``: one robot on an MQTT broker, and ``rovlink fleet``: every robot on it.

The pure parts — :mod:`broker` (the broker's address and credentials), :mod:`topics`,
:mod:`payloads` (what each topic carries), :mod:`commands` (the command topic's rules),
:mod:`outbox` and :mod:`fleet_view` — need no MQTT library; :mod:`bridge` runs them on aiomqtt.
"""
