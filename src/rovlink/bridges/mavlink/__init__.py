"""``rovlink mavlink``: the robot as an ArduSub-like MAVLink vehicle for ground stations.

The pure parts — :mod:`vehicle_state`, :mod:`parameters`, :mod:`pilot_input`, :mod:`failsafe`,
:mod:`telemetry_schedule` — hold every decision and need no MAVLink library; :mod:`endpoint`
(pymavlink) moves the messages and :mod:`bridge` runs them together on one event loop.
"""
