"""The benchmark: `rearrangement-bench` (command.py), its scene sets and trials (trials.py), the
Ray engine that runs them, their plots, OMPL logs, results table and candidate recordings."""
