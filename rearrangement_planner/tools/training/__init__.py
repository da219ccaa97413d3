"""The learned oracle's training: `rearrangement-train` (command.py) and its push data."""
