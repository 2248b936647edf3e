"""Bridges that put the robot into other worlds: MAVLink ground stations and MQTT brokers.

Each bridge stands on the asyncio host driver (:mod:`rovlink.aio`) and its event hook, like the
other tools: it sends commands of the table and never writes bytes behind the session.
"""
