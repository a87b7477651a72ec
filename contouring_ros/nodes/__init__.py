"""Thin rclpy nodes: each converts messages to arrays, calls the core, and publishes."""
