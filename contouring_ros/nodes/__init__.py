"""Thin rclpy nodes: each converts messages to arrays, calls the core, and publishes.

- :mod:`.interpolator`, :mod:`.plant`, :mod:`.servo`, :mod:`.contour_estimator`, :mod:`.ccc`,
  :mod:`.recorder`: one node per concern,
- :mod:`.lockstep`: the lean loop every node runs on (lockstep and realtime),
- :mod:`.parameters`: the nodes' ROS parameter descriptors,
- :mod:`.rclpy_adapter`: the one home of the rclpy internals the loops use,
- :mod:`.scripts`, :mod:`.explain`: the console scripts and a node's ``--help``.

Nothing is imported here."""
