"""The model's turn of the same box with and without the load shift (needs load_shift_3adc0cc.diff applied)."""
import sys, dataclasses, numpy as np
sys.argv += []
exec(open(__import__("pathlib").Path(__file__).with_name("height.py")).read().split("size = ")[0])
from rearrangement_planner.physics.options import PhysicsOptions
size = [0.06, 0.08, 0.16]; mu = 0.3
for offset in (0.0, 0.015, 0.03):
  for drop in (0.0, 0.03, 0.05, 0.06):
    box = {"name": "box", "shape": "box", "size": size, "pose": [0.46, offset, 0.0], "mass": 0.4, "support_friction": mu, "pusher_friction": 0.3}
    data = {"table": {"center": [0.55, 0.0], "size": [0.8, 1.2], "height": -drop}, "start_configuration": positions[0].tolist(), "objects": [box], "goal": {"object": "box", "position": [0.59, 0.0], "radius": 0.02}}
    scene = parse_scene(data, robot=panda)
    out = []
    for shift in (False, True):
        run = OpenLoopExecution(Physics(scene, dataclasses.replace(simulation_options(), max_substep=0.001, load_shift=shift)), scene.initial_state(), Command(times, positions), period=0.01)
        run.run(); m = run.state.objects[0]; out.append(f"x {m[0]:.3f} y {m[1]:+.3f} yaw {m[2]:+.2f}")
    print(offset, drop, " | ".join(out), flush=True)
