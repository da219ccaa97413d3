"""The product's 3D world (docs/design.md "The 3D world"): a scene as a MuJoCo model, one
execution stepped with its bookkeeping, and the planner's judge that executes a plan in many
worlds at once. Planning and execution both stand on it; it knows nothing of either."""
