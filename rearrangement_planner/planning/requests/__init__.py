"""The pipeline around a search: the plan request, the planner registry, raced trees, robust
selection's rollouts, shortcutting, trajectory timing, warm-up, the planner's status and the
retreat before a re-plan."""
