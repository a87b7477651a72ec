"""Pure numpy/scipy core of contouring_ros.

Nothing below this package imports rclpy, prints, logs or touches files: the in-process simulation and
the ROS node graph both call these objects, which is what makes a lockstep run of the graph reproduce
the in-process run to floating-point identity.
"""
