"""Nonprehensile whole-arm rearrangement planning: the ROS-free core."""
