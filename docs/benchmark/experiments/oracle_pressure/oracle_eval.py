import json, sys
from rearrangement_planner.tools import push_data, train
from rearrangement_planner.planning.planners.learned_oracle import load_models
nominal = push_data.generate(3000, seed=99, options=push_data.DataOptions(pressure=(1.0, 1.0), centre_offset=0.0))
drawn = push_data.generate(3000, seed=99)
for path in sys.argv[1:]:
    m = load_models(path)
    print(path, "nominal-pressure data", json.dumps(train.evaluate(m, nominal)))
    print(path, "drawn-pressure data  ", json.dumps(train.evaluate(m, drawn)))
