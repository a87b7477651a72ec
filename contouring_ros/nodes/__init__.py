"""Thin rclpy nodes: each converts messages to arrays, calls the core, and publishes.

- :mod:`.interpolator`, :mod:`.plant`, :mod:`.servo`, :mod:`.contour_estimator`, :mod:`.ccc`,
  :mod:`.recorder`: one node per concern,
- :mod:`.node`: :class:`~.node.LockstepNode`, the class every node subclasses, made of :mod:`.base` (parameters,
  inputs and outputs, the end of the run), :mod:`.intake` (what a node admits of its inputs), :mod:`.lockstep`
  and :mod:`.realtime` (the lean loops of the two timing modes),
- :mod:`.process`: a node's process (run_node: its entry point, signals, exit codes),
- :mod:`.parameters`: the nodes' ROS parameter descriptors,
- :mod:`.rclpy_adapter`: the one home of the rclpy internals the loops use,
- :mod:`.scripts`, :mod:`.explain`: the console scripts and a node's ``--help``.

Nothing is imported here."""
