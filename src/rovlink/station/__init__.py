"""The web ground station (``rovlink web``): a pilot's screen in the browser, served by Python.

* :class:`~rovlink.station.relay.ThrustRelay` — the pilot's stick to motion frames, with the
  dead-man rule and the watchdog that zeroes thrust when the input goes stale (sans-I/O).
* :class:`~rovlink.station.hub.Station` — one robot link shared by every browser: telemetry,
  link health, the event log, who is the pilot, and what each WebSocket message does.
* :mod:`rovlink.station.access` — who may connect: loopback by default, a token otherwise, and
  the Origin and Host checks.
* :func:`~rovlink.station.app.build_app` — the Starlette application (the page, its static
  assets and ``/ws``).

Starlette, uvicorn and websockets are the ``web`` extra; only :mod:`rovlink.station.app` and
:mod:`rovlink.station.serve` import them.
"""
