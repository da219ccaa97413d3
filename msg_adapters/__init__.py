"""Pure conversion functions between ROS 2 messages and the core's types.

The only package that knows both: it imports message types and the core, nothing else of ROS.
"""
