"""Running the node graph with rclpy: the layouts that start the nodes, and playing a bag back onto topics.

- :mod:`.runner`: every node its own process on a private ROS domain (``contouring-ros run``), with
  :mod:`.interruptions` (SIGINT and SIGTERM noted during a run, raised where the runner checks) and
  :mod:`.shared_memory` (the Fast DDS segments a killed node left in /dev/shm),
- :mod:`.composed`: every node its own rclpy node in one process (``layout: composed``),
- :mod:`.playback`: a bag republished at its recorded rate or as fast as possible (``contouring-ros play``).

The Fast DDS profiles the runner hands the nodes (``fastdds_profile.xml``: every socket on loopback;
``fastdds_profile_network.xml`` for ``network: true``) live beside them. Nothing is imported here."""
