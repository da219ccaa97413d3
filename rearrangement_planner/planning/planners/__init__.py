"""The planners: PC-RRT, the Static RRT, DARRT and the slice-based RRT with its oracles. They
build on the search machinery and know nothing of the request pipeline around them."""
