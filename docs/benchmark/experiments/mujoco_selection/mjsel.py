"""Study: choose among robust selection's candidates by MuJoCo perturbed executions instead of the model's rollouts.
Per scene (seed 0), up to 3 candidates (one tree each, its own 60 s), each: model robustness, MuJoCo score on 4 perturbed
worlds (seed 1000+k_seed, servo), and the evaluation the bench does (nominal servo + 5 perturbed worlds drawn from seed 0)."""
import sys, json, time, numpy as np
from pathlib import Path
from rearrangement_planner.execution.mujoco_check import check_execution, check_perturbed, ExecutionOptions
from rearrangement_planner.physics.step import Physics
from rearrangement_planner.tools.benchmark import load_trial_scene
from rearrangement_planner.planning.requests.pipeline import Candidates, candidate_seed
from rearrangement_planner.planning.requests.request import PlanRequest
from rearrangement_planner.planning.requests.robustness import goal_travel
from rearrangement_planner.planning.requests.trajectory import time_parameterize
from rearrangement_planner.planning.requests.warmup import warm_up
warm_up()
scene_files = sys.argv[2:]; out = open(sys.argv[1], "a"); seed = 0
servo = ExecutionOptions(arm="servo")
for path in scene_files:
    scene = load_trial_scene(path)
    request = PlanRequest.from_settings(scene, "pc-rrt", {"time_limit": 60.0, "trees": 1}, seed)
    physics = Physics(scene, request.physics)
    for k in range(3):
        k_seed = candidate_seed(seed, k)
        search = Candidates(request, physics, request.options.termination())
        found = search.plan(k_seed)
        rec = {"scene": Path(path).stem, "k": k, "solved": bool(found.solved), "search_s": round(found.plan_time, 3)}
        if found.solved:
            cand = search.shortcut(found, k_seed)
            t0 = time.monotonic(); score = search.judge(cand, k_seed); rt = time.monotonic() - t0
            traj = time_parameterize(scene.robot, cand.result.arm_path, request.timing)
            t0 = time.monotonic(); mj = check_perturbed(scene, traj, 4, 1000 + k_seed, servo); mt = time.monotonic() - t0
            nom = check_execution(scene, traj, None, servo)
            ev = check_perturbed(scene, traj, 5, seed, servo)
            rec.update(shortcut_s=round(cand.shortcut_time, 3), rollouts_s=round(rt, 3), robustness=score,
                       travel=round(goal_travel(scene, cand.result.states), 4), mj_score=mj.reached / 4, mj_s=round(mt, 2),
                       reached=bool(nom.reached), toppled=len(nom.toppled), eval_reached=ev.reached, traj_s=round(traj.duration, 1))
        out.write(json.dumps(rec) + "\n"); out.flush()
