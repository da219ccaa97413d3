"""The search machinery the planners share: the planner interface and outcome codes, the one
termination condition, Project and the pushing manifold, ConstrainedProp (compiled), the tree,
one plan call's bookkeeping, the approach onto the plane and the closed-loop push policy. It
imports nothing from the planners or the request pipeline (`test/test_architecture.py`)."""
