"""The wire contract: what the graph's nodes are and what they exchange, shared by every layout that runs them.

- :mod:`.catalogue`: every node concern once, in graph order (console script, class, inputs, outputs; standard
  library only: setup.py reads it by path),
- :mod:`.graph`: the node specs, topics, message layouts and QoS of a graph for given axes,
- :mod:`.cdr`: the graph's three hot message types encoded and decoded directly.

Nothing is imported here."""
