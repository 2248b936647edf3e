"""``rovlink monitor``: a live terminal dashboard of the robot, built on textual.

The textual app is :mod:`rovlink.monitor.app` (imported only by the command); everything it shows
is computed by plain modules that know nothing of textual: :mod:`~rovlink.monitor.readings`
(what arrived and when), :mod:`~rovlink.monitor.controls` (which frames a key sends),
:mod:`~rovlink.monitor.chart` (depth over time), :mod:`~rovlink.monitor.compass` (heading
tape, attitude bars) and :mod:`~rovlink.monitor.panels` (the panels' text).
"""
