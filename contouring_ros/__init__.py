"""contouring_ros: multi-axis contouring control of CNC feed drives on ROS 2."""

__version__ = "0.1.0"
