"""The harness around the planner node, not the product: `world_sim` (a simulated cell),
`replay` (bags played into the node), `make_bags` (the shipped input bags) and `node_demo`
(`make demo`)."""
