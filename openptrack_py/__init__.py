"""openptrack_py: multi-sensor people tracking for creative apps.

Depth sensors detect people locally and publish compact detections over Zenoh; one
tracker fuses them on the ground plane; output nodes send OpenPTrack-compatible JSON
over UDP, OSC, WebSocket and Zenoh. A simulator makes everything runnable without a
camera.

Quick start (faster than real time, no network)::

    >>> from openptrack_py.sim import Simulator, build_scenario
    >>> sim = Simulator(build_scenario("crowd", seed=1, duration_s=5.0))
    >>> for event in sim.events():
    ...     batch = event.batch  # a DetectionBatch from one virtual sensor
"""

__version__ = "0.1.0"
