"""The benchmark's figures (matplotlib, Agg backend), after King et al. 2015, §V, from trials.csv
rows (`benchmark.CSV_COLUMNS`) and the summary (`benchmark.summarize`):

- success_vs_budget.png (Fig. 7): for each time budget t, the share of trials solved with a
  plan time of at most t, per planner;
- plan_time.png (Fig. 4): (a) share of trials solved, (b) plan times of the solved trials;
- shortcut.png (Fig. 8): (a) arm path length and (b) total object displacement before and
  after shortcutting (the planners whose paths are shortcut);
- by_objects.png: share solved per number of movable objects;
- end_to_end.png (the headline): share of requests solved in the planner's model and reached
  when the plan is executed open loop in MuJoCo (ideal and servo-driven arm), per planner,
  beside the paper's real-robot executions (Table I);
- success_vs_iterations.png (Fig. 2b of Haustein et al. 2018): for each iteration count n, the
  share of trials solved within n iterations, per planner;
- reliability.png: the robustness score against the share of perturbed MuJoCo executions that
  reach the goal, per fifth of the score range (`benchmark.calibration`), with the Brier score.

`plot_manipulation_states` draws Fig. 2a of Haustein et al. 2018 from a learned oracle, and
`plot_training` the loss curves of its training (`rearrangement-train --report`).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from rearrangement_planner.tools.bench.trials import (  # noqa: E402
    PAPER,
    SHORTCUT_PLANNERS,
    calibration,
    planner_variant,
    success_at,
)

COLORS = {"pc-rrt": "#2ca02c", "static-rrt": "#9467bd", "darrt": "#ff7f0e",
          "slice-rrt": "#1f77b4", "slice-rrt:oracle=hand": "#17becf"}
LABELS = {"pc-rrt": "PC-RRT", "static-rrt": "Static RRT", "darrt": "DARRT",
          "slice-rrt": "slice-RRT, learned", "slice-rrt:oracle=learned": "slice-RRT, learned",
          "slice-rrt:oracle=hand": "slice-RRT, hand-made"}
DPI = 110


def _color(planner: str) -> str:
    """The planner's colour; a label with settings (`pc-rrt:trees=1`) takes its planner's."""
    return COLORS.get(planner, COLORS.get(planner.partition(":")[0], "#7f7f7f"))


def _label(planner: str) -> str:
    """The tick label: the planner's name, and a label's settings one per line below it, so
    that long labels do not run into each other."""
    if planner in LABELS:
        return LABELS[planner]
    name, _, settings = planner.partition(":")
    return "\n".join([LABELS.get(name, name), *filter(None, settings.split(","))])


def _of(rows: Sequence[dict], planner: str) -> list[dict]:
    return [r for r in rows if r["planner"] == planner]


def _solved(rows: Sequence[dict]) -> list[dict]:
    return [r for r in rows if r["solved"] == "1"]


def _save(fig, path: Path) -> Path:
    fig.tight_layout()
    fig.savefig(path, dpi=DPI)
    plt.close(fig)
    return path


def plot_success_vs_budget(rows: Sequence[dict], planners: Sequence[str], time_limit: float,
                           path: Path) -> Path:
    """Fig. 7 of King et al.: expected success given a time budget."""
    fig, ax = plt.subplots(figsize=(6.4, 4.2))
    grid = np.linspace(0.0, time_limit, 801)
    for planner in planners:
        group = _of(rows, planner)
        if not group:
            continue
        share = [100 * success_at(group, t) for t in grid]
        ax.step(grid, share, where="post", color=_color(planner), lw=2,
                label=f"{_label(planner)} ({len(group)} trials)")
    paper = PAPER["solved_share_at_300s"]
    ax.text(0.02, 0.97, "King et al. at 300 s: " + ", ".join(
        f"{_label(p)} {100 * v:.0f} %" for p, v in paper.items()), transform=ax.transAxes,
        va="top", fontsize=8, color="0.35")
    ax.axvline(5.0, color="0.8", lw=1, ls=":", zorder=0)
    ax.set_xlim(0, time_limit)
    ax.set_ylim(-2, 102)
    ax.set_xlabel("time budget (s)")
    ax.set_ylabel("trials solved within the budget (%)")
    ax.set_title("Success rate vs time budget (cf. Fig. 7)")
    ax.grid(alpha=0.3)
    ax.legend(loc="upper left", bbox_to_anchor=(0.0, 0.93), fontsize=9)
    return _save(fig, path)


def plot_plan_times(rows: Sequence[dict], planners: Sequence[str], path: Path) -> Path:
    """Fig. 4 of King et al.: (a) success rate, (b) plan time of the solved trials."""
    planners = [p for p in planners if _of(rows, p)]
    fig, (ax_a, ax_b) = plt.subplots(1, 2, figsize=(9.0, 4.0),
                                     gridspec_kw={"width_ratios": [1, 1.6]})
    x = np.arange(len(planners))
    shares = [100 * len(_solved(_of(rows, p))) / len(_of(rows, p)) for p in planners]
    ax_a.bar(x, shares, color=[_color(p) for p in planners], width=0.6)
    for xi, p, share in zip(x, planners, shares, strict=True):
        ax_a.text(xi, share + 1.5, f"{len(_solved(_of(rows, p)))}/{len(_of(rows, p))}",
                  ha="center", fontsize=9)
    ax_a.set_xticks(x, [_label(p) for p in planners])
    ax_a.set_ylim(0, 110)
    ax_a.set_ylabel("trials solved (%)")
    ax_a.set_title("(a) success rate")
    rng = np.random.default_rng(0)   # jitter of the strip plot, the same every time
    times = [[float(r["plan_time_s"]) for r in _solved(_of(rows, p))] for p in planners]
    if any(times):
        ax_b.boxplot([t if t else [np.nan] for t in times], positions=x, widths=0.5,
                     showfliers=False, medianprops={"color": "black"})
    for xi, p, t in zip(x, planners, times, strict=True):
        ax_b.scatter(xi + rng.uniform(-0.18, 0.18, len(t)), t, s=14, color=_color(p),
                     alpha=0.7, zorder=3)
        if t:
            ax_b.text(xi, 1.02, f"median {np.median(t):.1f} s", ha="center", fontsize=8,
                      transform=ax_b.get_xaxis_transform())
        else:
            ax_b.text(xi, 0.5, "none solved", ha="center", fontsize=8,
                      transform=ax_b.get_xaxis_transform())
    ax_b.set_xticks(x, [_label(p) for p in planners])
    ax_b.set_xlim(-0.6, len(planners) - 0.4)
    ax_b.set_ylim(bottom=0)
    ax_b.set_ylabel("plan time of solved trials (s)")
    ax_b.set_title("(b) plan time", pad=16)
    ax_b.grid(axis="y", alpha=0.3)
    fig.suptitle("Success rate and plan time per planner (cf. Fig. 4)")
    return _save(fig, path)


def plot_shortcut(rows: Sequence[dict], planners: Sequence[str], path: Path) -> Path:
    """Fig. 8 of King et al.: (a) manipulator path length, (b) total object displacement,
    before and after shortcutting; bars are means, dots single trials, lines join the two
    values of one trial."""
    planners = [p for p in planners
                if planner_variant(p)[0] in SHORTCUT_PLANNERS and _solved(_of(rows, p))]
    fig, axes = plt.subplots(1, 2, figsize=(9.0, 4.0))
    panels = (("path_length_rad", "arm path length (rad)", "(a) manipulator path length"),
              ("object_displacement_m", "total object displacement (m)",
               "(b) object displacement"))
    for ax, (field, ylabel, title) in zip(axes, panels, strict=True):
        ax.set_title(title, pad=16)
        ax.set_ylabel(ylabel)
        if not planners:
            ax.text(0.5, 0.5, "no solved trial of a shortcut planner", ha="center",
                    transform=ax.transAxes)
            ax.set_xticks([])
            continue
        ticks, names = [], []
        for k, planner in enumerate(planners):
            solved = _solved(_of(rows, planner))
            before = np.array([float(r[f"{field}_before"]) for r in solved])
            after = np.array([float(r[f"{field}_after"]) for r in solved])
            xb, xa = 3 * k, 3 * k + 1
            ax.bar([xb, xa], [before.mean(), after.mean()], width=0.8,
                   color=[_color(planner), _color(planner)], alpha=0.45,
                   edgecolor=_color(planner), hatch=["", "//"])
            for b, a in zip(before, after, strict=True):
                ax.plot([xb, xa], [b, a], color="0.5", lw=0.6, alpha=0.6)
            ax.scatter(np.full(len(before), xb), before, s=10, color="0.25", zorder=3)
            ax.scatter(np.full(len(after), xa), after, s=10, color="0.25", zorder=3)
            change = 100 * (after.mean() / before.mean() - 1) if before.mean() > 0 else 0.0
            ax.text(xb + 0.5, 1.01, f"{change:+.0f} %", ha="center", fontsize=9,
                    transform=ax.get_xaxis_transform())
            ticks += [xb, xa]
            names += [f"{_label(planner)}\nbefore", "after"]
        ax.set_xticks(ticks, names, fontsize=8)
        ax.set_ylim(bottom=0)
        ax.grid(axis="y", alpha=0.3)
    fig.suptitle(f"Shortcutting (cf. Fig. 8; King et al.: "
                 f"{-100 * PAPER['shortcut_arm_path_reduction']:.0f} % arm path length)")
    return _save(fig, path)


def plot_by_objects(rows: Sequence[dict], planners: Sequence[str], path: Path) -> Path:
    """Share of trials solved per number of movable objects, per planner."""
    fig, ax = plt.subplots(figsize=(6.4, 4.0))
    counts = sorted({int(r["objects"]) for r in rows})
    for planner in planners:
        group = _of(rows, planner)
        if not group:
            continue
        shares = [100 * len(_solved([r for r in group if int(r["objects"]) == n]))
                  / max(1, len([r for r in group if int(r["objects"]) == n])) for n in counts]
        ax.plot(counts, shares, "o-", color=_color(planner), label=_label(planner))
    ax.set_xticks(counts)
    ax.set_ylim(-5, 105)
    ax.set_xlabel("movable objects in the scene")
    ax.set_ylabel("trials solved (%)")
    ax.set_title("Success rate per number of objects")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=9)
    return _save(fig, path)


def plot_end_to_end(rows: Sequence[dict], planners: Sequence[str], path: Path) -> Path:
    """The headline, per planner: the share of requests solved in the model and the share
    whose plan reaches the goal executed open loop in MuJoCo (ideal arm; servo arm, the
    end-to-end figure, labelled)."""
    fig, ax = plt.subplots(figsize=(max(6.4, 1.7 * len(planners)), 4.0))
    bars = (("solved", "solved in the model", 1.0), ("executed_ideal", "reached, ideal arm", 0.7),
            ("executed_servo", "reached, servo arm (end to end)", 0.4))
    width = 0.8 / len(bars)
    for i, planner in enumerate(planners):
        group = _of(rows, planner)
        for j, (column, label, alpha) in enumerate(bars):
            share = 100 * sum(r.get(column) == "1" for r in group) / max(1, len(group))
            x = i + (j - 1) * width
            ax.bar(x, share, width, color=_color(planner), alpha=alpha,
                   label=label if i == 0 else None, edgecolor="black", linewidth=0.5)
            if column == "executed_servo":
                ax.text(x, share + 1, f"{share:.0f} %", ha="center", fontsize=8)
    real = PAPER["executed_real_robot_share"]["pc-rrt"]
    ax.axhline(100 * real, color="gray", linestyle="--", linewidth=1,
               label=f"King et al., real robot ({100 * real:.0f} % of executions)")
    ax.set_xticks(range(len(planners)), [_label(p) for p in planners], fontsize=8)
    ax.set_ylim(0, 105)
    ax.set_ylabel("requests (%)")
    ax.set_title("End to end: requests whose plan reaches the goal executed open loop")
    ax.grid(alpha=0.3, axis="y")
    ax.legend(fontsize=8)
    return _save(fig, path)


def plot_reliability(rows: Sequence[dict], planners: Sequence[str], path: Path) -> Path:
    """The reliability diagram of the robustness score: per fifth of the score range, the
    share of the plans' perturbed MuJoCo executions that reached the goal against the plans'
    mean score (the diagonal is a calibrated score), per planner, with its Brier score."""
    fig, ax = plt.subplots(figsize=(5.2, 5.0))
    ax.plot([0, 1], [0, 1], color="gray", linestyle="--", linewidth=1, label="calibrated")
    ax.fill_between([0, 1], [-0.15, 0.85], [0.15, 1.15], color="gray", alpha=0.12,
                    label="within 0.15")
    for planner in planners:
        cal = calibration(_solved(_of(rows, planner)))
        points = [(b["mean_score"], b["reached_share"], b["plans"]) for b in cal["bins"]
                  if b["mean_score"] is not None and b["reached_share"] is not None]
        if not points:
            continue
        x, y, n = (np.array(v) for v in zip(*points, strict=True))
        ax.plot(x, y, "o-", color=_color(planner),
                label=f"{_label(planner)} (Brier {cal['brier']:.3f}, {cal['plans']} plans)")
        for xi, yi, ni in zip(x, y, n, strict=True):
            ax.annotate(str(ni), (xi, yi), textcoords="offset points", xytext=(4, -10),
                        fontsize=7, color=_color(planner))
    ax.set_xlim(0, 1)
    ax.set_ylim(0, 1)
    ax.set_xlabel("robustness score (mean in bin)")
    ax.set_ylabel("perturbed MuJoCo executions reaching the goal")
    ax.set_title("Is the robustness score honest?")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="upper left")
    return _save(fig, path)


def plot_success_vs_iterations(rows: Sequence[dict], planners: Sequence[str],
                               path: Path) -> Path:
    """Fig. 2b of Haustein et al. 2018: the share of trials solved within n iterations."""
    fig, ax = plt.subplots(figsize=(6.4, 4.2))
    most = max([int(r["iterations"]) for r in rows] + [10])
    grid = np.unique(np.geomspace(1, most, 400).astype(int))
    for planner in planners:
        group = _of(rows, planner)
        if not group:
            continue
        solved = np.array([int(r["iterations"]) for r in _solved(group)])
        share = [100 * np.sum(solved <= n) / len(group) for n in grid]
        ax.step(grid, share, where="post", color=_color(planner), lw=2,
                label=f"{_label(planner)} ({len(group)} trials)")
    ax.set_xscale("log")
    ax.set_ylim(-2, 102)
    ax.set_xlabel("iterations")
    ax.set_ylabel("trials solved within n iterations (%)")
    ax.set_title("Success rate vs iterations (cf. Haustein et al. 2018, Fig. 2b)")
    ax.grid(alpha=0.3)
    ax.legend(loc="upper left", fontsize=9)
    return _save(fig, path)


def plot_manipulation_states(models, path: Path, samples: int = 300, seed: int = 0) -> Path:
    """Fig. 2a of Haustein et al. 2018: tool poses the learned generator proposes around an
    object at the origin for the push drawn as an arrow, coloured by the tool's yaw (an arrow
    per pose points where the hand faces). `models`:
    `planning.planners.learned_oracle.OracleModels`."""
    from matplotlib.patches import Circle, Rectangle

    rng = np.random.default_rng(seed)
    goal_box = np.array([0.0, 0.06, 0.08, 0.12, 0.4, 0.45, 0.35])
    cases = [("goal box (6 x 8 cm), push +y", goal_box, (0.0, 0.2)),
             ("goal box, push +x", goal_box, (0.2, 0.0)),
             ("cylinder r = 4 cm, push (+x, +y)", np.array([1.0, 0.08, 0.08, 0.12, 0.4, 0.45,
                                                             0.35]), (0.14, 0.14))]
    fig, axes = plt.subplots(1, len(cases), figsize=(4.2 * len(cases), 4.4))
    for ax, (title, props, desired) in zip(axes, cases, strict=True):
        z = rng.standard_normal((samples, models.networks["generator"].weights[0].shape[0]
                                 - 2 - len(props)))
        tools = models.generate(z, np.tile(desired, (samples, 1)), np.tile(props, (samples, 1)))
        if props[0] > 0.5:
            ax.add_patch(Circle((0, 0), props[1] / 2, color="0.6"))
        else:
            ax.add_patch(Rectangle((-props[1] / 2, -props[2] / 2), props[1], props[2],
                                   color="0.6"))
        ax.quiver(tools[:, 0], tools[:, 1], np.cos(tools[:, 2]), np.sin(tools[:, 2]),
                  (tools[:, 2] + np.pi) / (2 * np.pi), cmap="hsv", clim=(0, 1), scale=30,
                  width=0.004)
        ax.annotate("", xy=desired, xytext=(0, 0),
                    arrowprops={"arrowstyle": "->", "lw": 2, "color": "black"})
        ax.set_xlim(-0.25, 0.25)
        ax.set_ylim(-0.25, 0.25)
        ax.set_aspect("equal")
        ax.set_title(title, fontsize=10)
        ax.set_xlabel("x in the object frame (m)")
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("y (m)")
    fig.suptitle("Learned manipulation states (cf. Haustein et al. 2018, Fig. 2a): tool poses "
                 "from the generator, coloured and pointing by the hand's yaw", fontsize=10)
    return _save(fig, path)


def plot_training(report: dict, path: Path) -> Path:
    """The loss curves of a `rearrangement-train` report (`Trainer.report`), one panel per
    stage, against the training step."""
    curves = report["curves"]
    panels = [("forward models (MSE of mean + log variance)", ["forward"]),
              ("policy (L of Eq. 2, m²)", ["policy"]),
              ("conditional GAN", ["discriminator", "generator"])]
    fig, axes = plt.subplots(1, len(panels), figsize=(13, 3.6))
    steps = report["options"]
    totals = {"forward": steps["forward_steps"], "policy": steps["policy_steps"],
              "discriminator": steps["gan_steps"], "generator": steps["gan_steps"]}
    for ax, (title, names) in zip(axes, panels, strict=True):
        for name in names:
            values = curves.get(name, [])
            x = np.linspace(0, totals[name], len(values))
            ax.plot(x, values, lw=1.5, label=name)
        ax.set_title(title, fontsize=10)
        ax.set_xlabel("step")
        ax.grid(alpha=0.3)
        if len(names) > 1:
            ax.legend(fontsize=8)
    seconds = report.get("seconds", {})
    fig.suptitle(f"rearrangement-train --seed {report['seed']}: " + ", ".join(
        f"{k} {v:.0f} s" for k, v in seconds.items()), fontsize=10)
    return _save(fig, path)


def plot_all(rows: Sequence[dict], summary: dict, out: Path) -> list[Path]:
    """Write the seven figures into `out`; returns their paths."""
    protocol = summary["protocol"]
    planners = list(protocol["planners"])
    return [
        plot_success_vs_budget(rows, planners, float(protocol["time_limit"]),
                               out / "success_vs_budget.png"),
        plot_plan_times(rows, planners, out / "plan_time.png"),
        plot_shortcut(rows, planners, out / "shortcut.png"),
        plot_by_objects(rows, planners, out / "by_objects.png"),
        plot_end_to_end(rows, planners, out / "end_to_end.png"),
        plot_success_vs_iterations(rows, planners, out / "success_vs_iterations.png"),
        plot_reliability(rows, planners, out / "reliability.png"),
    ]
