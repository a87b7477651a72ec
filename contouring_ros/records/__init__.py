"""Recorded runs: bags and what is read from them, with no rclpy.

- :mod:`.bag_writer`: MCAP bags in the rosbag2 layout, written (the recorder's, and in-process runs),
- :mod:`.bag_reader`: MCAP bags read, hardened (bounded whatever a file holds; damaged chunks skipped),
- :mod:`.bag`: a bag decoded into a run, checked against its experiment,
- :mod:`.scoring`: the scores of a run (bag or in-process result) and their tables,
- :mod:`.blocks`: results per block of a tool path run,
- :mod:`.export`: a run's per-step signals and exact contour error as CSV,
- :mod:`.comparison`: runs compared: their names, scores side by side and as ratios, how their experiments differ,
- :mod:`.replay`: estimators replayed over a recorded run against its exact contour error,
- :mod:`.traces`: runs made ready to draw (one name and one colour each, exact contour error, reference path),
- :mod:`.figures`: the figures of a run or a comparison (matplotlib), written as PNG files,
- :mod:`.html_report`: a self-contained HTML report of a run or a comparison,
- :mod:`.numbers`: numbers as text, for every table, report and CSV file,
- :mod:`.outputs`: what a command may write (never an input, never a user's file without ``--force``).

Nothing is imported here."""
