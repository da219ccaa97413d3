"""Executing plans: open loop in the planner's physics (`open_loop`)."""
