"""`rearrangement-train`: learn the slice-based RRT's oracle for one robot (Haustein et al. 2018,
§II), with JAX and optax on the CPU, and write it as the small .npz the planner reads with NumPy
(`planning/planners/learned_oracle.py`).

Stages, each from the same seed (the same seed and options give the same weights):

1. data: single-object pushes through the planner's physics under pose and friction noise
   (`tools/training/push_data.py`);
2. the forward models f_μ and f_σ² (Eq. 3-4), supervised on each sample's mean successor
   and the log of its variance;
3. the policy π_θ(x_r, x_o^d, ν_o), by deterministic policy gradient (Silver et al. 2014)
   through the frozen forward models on the loss of Eq. 2:
   L_θ = Σ_j σ_j (Var[x'_oj] + (E[x'_oj] - x^d_oj)²), over tool poses of the data and random
   targets;
4. the generator: Metropolis-Hastings chains on p(x_r) ∝ exp(-λ L_θ(x_r)) (Eq. 5) for random
   conditions (x_o^d, ν_o), then a conditional GAN (Eq. 6-7) trained on those samples.

JAX is imported here only: planning needs NumPy alone.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from rearrangement_planner.model.resources import default_robot
from rearrangement_planner.planning.planners.learned_oracle import (
    NETWORKS,
    NOISE_SIZE,
    POSITION_SCALE,
    forward_inputs,
    forward_output,
    generator_output,
    mlp,
    model_path,
    policy_output,
    property_features,
    save_models,
    tool_features,
)
from rearrangement_planner.tools.training.push_data import DataOptions, PushData, generate


@dataclass(frozen=True)
class TrainOptions:
    """Sizes and steps of one training run; `tiny()` is the tests' few-second version."""

    samples: int = 100000
    """Pushes simulated for the forward models."""
    hidden: tuple[int, ...] = (256, 256, 256)
    """Hidden layer widths of every network."""
    batch: int = 512
    forward_steps: int = 30000
    policy_steps: int = 10000
    chains: int = 4096
    """MCMC chains, one condition each."""
    mcmc_steps: int = 600
    gan_steps: int = 20000
    learning_rate: float = 1e-3
    loss_weights: tuple[float, float, float] = (1.0, 1.0, 0.01)
    """σ_j of Eq. 2 for x, y (per m²) and yaw (per rad²): 10 cm of error weigh as 1 rad."""
    temperature: float = 400.0
    """λ of Eq. 5, per m²: a loss 0.005 m² higher is e^-2 as likely."""
    data: DataOptions = field(default_factory=DataOptions)

    @classmethod
    def tiny(cls) -> TrainOptions:
        return cls(samples=300, hidden=(32, 32), batch=64, forward_steps=150, policy_steps=100,
                   chains=64, mcmc_steps=30, gan_steps=100,
                   data=DataOptions(noise_draws=3, arm_states=3))


def _jax() -> Any:
    try:
        import jax
    except ImportError as error:    # the training extra is not installed
        raise SystemExit("rearrangement-train needs JAX and optax: pip install jax optax "
                         f"({error})") from error
    jax.config.update("jax_enable_x64", False)
    return jax


def init_network(key: Any, sizes: list[int], last_scale: float = 1.0) -> tuple[list, list]:
    """He-initialised weights and zero biases of a perceptron with layer `sizes`; the output
    layer's weights scaled by `last_scale` (small: outputs start near 0, where the policy's
    tanh and logistic are not saturated)."""
    jax = _jax()
    weights, biases = [], []
    for i, (n_in, n_out) in enumerate(zip(sizes[:-1], sizes[1:], strict=True)):
        key, sub = jax.random.split(key)
        scale = math.sqrt(2.0 / n_in) * (last_scale if i == len(sizes) - 2 else 1.0)
        weights.append(jax.random.normal(sub, (n_in, n_out)) * scale)
        biases.append(jax.numpy.zeros(n_out))
    return weights, biases


def _apply(network: Any, x: Any) -> Any:
    """A perceptron given as (weights, biases) applied to x with JAX."""
    import jax.numpy as jnp

    return mlp(network[0], network[1], x, jnp)


def _fit(loss: Callable, params: Any, steps: int, learning_rate: float, batches: Callable,
         log: Callable[[int, float], None]) -> Any:
    """Adam on `loss(params, batch)` for `steps` steps; `batches(step)` gives each batch."""
    jax = _jax()
    import optax

    optimizer = optax.adam(learning_rate)
    state = optimizer.init(params)

    @jax.jit
    def update(params: Any, state: Any, batch: Any) -> tuple[Any, Any, Any]:
        value, grads = jax.value_and_grad(loss)(params, batch)
        updates, state = optimizer.update(grads, state)
        return optax.apply_updates(params, updates), state, value

    for step in range(steps):
        params, state, value = update(params, state, batches(step))
        log(step, float(value))
    return params


class Trainer:
    """One training run (`TrainOptions`), its loss curves in `curves`."""

    def __init__(self, options: TrainOptions, seed: int, say: Callable[[str], None] = print,
                 workers: int = 1):
        self.options = options
        self.workers = workers
        self.seed = seed
        self.say = say
        self.jax = _jax()
        self.key = self.jax.random.PRNGKey(seed)
        self.rng = np.random.default_rng(seed)
        self.curves: dict[str, list[float]] = {}
        self.params: dict[str, tuple[list, list]] = {}
        self.seconds: dict[str, float] = {}

    def _key(self) -> Any:
        self.key, sub = self.jax.random.split(self.key)
        return sub

    def _logger(self, name: str, steps: int) -> Callable[[int, float], None]:
        curve = self.curves.setdefault(name, [])
        every = max(1, steps // 200)
        window: list[float] = []

        def log(step: int, value: float) -> None:
            window.append(value)
            if (step + 1) % every == 0 or step == steps - 1:
                curve.append(float(np.mean(window)))
                window.clear()
            if (step + 1) % max(1, steps // 5) == 0:
                self.say(f"  {name}: step {step + 1}/{steps}, loss {curve[-1]:.5g}")
        return log

    def _net(self, n_in: int, n_out: int, last_scale: float = 1.0) -> tuple[list, list]:
        return init_network(self._key(), [n_in, *self.options.hidden, n_out], last_scale)

    def _batches(self, arrays: tuple[np.ndarray, ...]) -> Callable[[int], tuple]:
        n = len(arrays[0])
        order = self.rng.integers(0, n, (1 << 16, self.options.batch))

        def batch(step: int) -> tuple:
            rows = order[step % len(order)]
            return tuple(a[rows] for a in arrays)
        return batch

    # -- stages ----------------------------------------------------------------------------------

    def data(self, cache: Path | None = None) -> PushData:
        """The pushes: read from `cache` when it holds this run's (same seed and options),
        else simulated (and written there)."""
        start = time.monotonic()
        stamp = json.dumps([self.seed, self.options.samples, asdict(self.options.data)])
        if cache is not None and cache.is_file():
            with np.load(cache) as saved:
                if str(saved["stamp"]) == stamp:
                    self.say(f"  read {cache}")
                    return PushData.load(cache)
        data = generate(self.options.samples, self.seed, self.options.data,
                        workers=self.workers)
        if cache is not None:
            data.save(cache, stamp=stamp)
        self.seconds["data"] = time.monotonic() - start
        return data

    def forward_models(self, data: PushData) -> None:
        """f_μ and f_σ²: the mean successor (MSE) and the log of its variance (MSE)."""
        jnp, opts = self.jax.numpy, self.options
        speed, duration = opts.data.max_speed, opts.data.max_duration
        scale = np.array([POSITION_SCALE, POSITION_SCALE, 1.0])
        inputs = forward_inputs(data.tool, data.properties, data.action, speed, duration)
        mean = data.successors.mean(axis=1) / scale
        log_var = np.log(data.successors.var(axis=1) / scale ** 2 + 1e-4)
        arrays = tuple(np.asarray(a, dtype=np.float32) for a in (inputs, mean, log_var))

        def loss(params: Any, batch: tuple) -> Any:
            x, mu, lv = batch
            return (jnp.mean((_apply(params["f_mu"], x) - mu) ** 2)
                    + jnp.mean((_apply(params["f_var"], x) - lv) ** 2))

        start = time.monotonic()
        params = {"f_mu": self._net(inputs.shape[1], 3), "f_var": self._net(inputs.shape[1], 3)}
        params = _fit(loss, params, opts.forward_steps, opts.learning_rate,
                      self._batches(arrays), self._logger("forward", opts.forward_steps))
        self.params.update(params)
        self.seconds["forward"] = time.monotonic() - start

    def _loss_fn(self) -> Callable:
        """L_θ(x_r, x_o^d, ν_o) of Eq. 2 for a policy's parameters, through the forward models."""
        jnp, opts = self.jax.numpy, self.options
        speed, duration = opts.data.max_speed, opts.data.max_duration
        weights = jnp.asarray(opts.loss_weights)
        f_mu, f_var = self.params["f_mu"], self.params["f_var"]

        def loss(policy: Any, tool: Any, desired: Any, props: Any) -> Any:
            tf, pf = tool_features(tool, jnp), property_features(props, jnp)
            u = policy_output(_apply(policy, jnp.concatenate(
                [tf, desired / POSITION_SCALE, pf], axis=-1)), speed, duration, jnp)
            x = forward_inputs(tool, props, u, speed, duration, jnp)
            mu, var = forward_output(_apply(f_mu, x), _apply(f_var, x), jnp)
            target = jnp.concatenate([desired, jnp.zeros_like(desired[..., :1])], axis=-1)
            return jnp.sum(weights * (var + (mu - target) ** 2), axis=-1)
        return loss

    def _targets(self, n: int, tool: np.ndarray | None = None) -> np.ndarray:
        """Desired object displacements x_o^d, 2 cm to one push's reach: for `tool` poses,
        mostly away from the tool (where a push from there can send the object; the states the
        generator proposes), else in a uniform heading."""
        reach = self.options.data.max_speed * self.options.data.max_duration
        heading = self.rng.uniform(-math.pi, math.pi, n)
        if tool is not None:
            away = np.arctan2(-tool[:, 1], -tool[:, 0]) + self.rng.normal(0.0, 0.5, n)
            heading = np.where(self.rng.random(n) < 0.7, away, heading)
        distance = self.rng.uniform(0.02, reach, n)
        return np.column_stack([distance * np.cos(heading), distance * np.sin(heading)])

    def policy(self, data: PushData) -> None:
        """π_θ by deterministic policy gradient on L_θ over the data's tool poses and objects."""
        jnp, opts = self.jax.numpy, self.options
        loss_of = self._loss_fn()
        n = len(data.tool)
        arrays = tuple(np.asarray(a, dtype=np.float32)
                       for a in (data.tool, self._targets(n, data.tool), data.properties))

        def loss(params: Any, batch: tuple) -> Any:
            return jnp.mean(loss_of(params["policy"], *batch))

        start = time.monotonic()
        params = {"policy": self._net(4 + 2 + 7, 3, last_scale=0.01)}
        params = _fit(loss, params, opts.policy_steps, opts.learning_rate,
                      self._batches(arrays), self._logger("policy", opts.policy_steps))
        self.params.update(params)
        self.seconds["policy"] = time.monotonic() - start

    def mcmc(self, data: PushData) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Samples of p(x_r | x_o^d, ν_o) ∝ exp(-λ L_θ) (Eq. 5), one Metropolis-Hastings chain
        per condition, its last state kept. x_r is confined to where the data has tool poses:
        outside the object's footprint circle and within `DataOptions.reach` of it."""
        jax, jnp, opts = self.jax, self.jax.numpy, self.options
        n = opts.chains
        rows = self.rng.integers(0, len(data.tool), n)
        props = jnp.asarray(data.properties[rows], dtype=jnp.float32)
        desired = jnp.asarray(self._targets(n), dtype=jnp.float32)
        footprint = jnp.where(props[:, 0] > 0.5, 0.5 * props[:, 1],
                              0.5 * jnp.hypot(props[:, 1], props[:, 2]))
        loss_of = self._loss_fn()
        policy = self.params["policy"]
        reach = opts.data.reach

        def energy(tool: Any) -> Any:
            distance = jnp.hypot(tool[:, 0], tool[:, 1]) - footprint
            inside = (distance >= 0.0) & (distance <= reach)
            return jnp.where(inside, opts.temperature * loss_of(policy, tool, desired, props),
                             jnp.inf)

        @jax.jit
        def step(carry: tuple, key: Any) -> tuple:
            tool, e = carry
            k1, k2 = jax.random.split(key)
            proposal = tool + jax.random.normal(k1, tool.shape) * jnp.array([0.02, 0.02, 0.3])
            e_new = energy(proposal)
            accept = jnp.log(jax.random.uniform(k2, (n,))) < e - e_new
            return (jnp.where(accept[:, None], proposal, tool),
                    jnp.where(accept, e_new, e)), accept.mean()

        start = time.monotonic()
        bearing = self.rng.uniform(-math.pi, math.pi, n)
        radius = np.asarray(footprint) + self.rng.uniform(0.0, reach, n)
        tool = jnp.asarray(np.column_stack([radius * np.cos(bearing), radius * np.sin(bearing),
                                            self.rng.uniform(-math.pi, math.pi, n)]),
                           dtype=jnp.float32)
        carry = (tool, energy(tool))
        keys = jax.random.split(self._key(), opts.mcmc_steps)
        (tool, e), accepted = jax.lax.scan(step, carry, keys)
        self.curves["mcmc_acceptance"] = [float(a) for a in np.asarray(accepted)[::10]]
        self.seconds["mcmc"] = time.monotonic() - start
        mean_loss = float(np.mean(e)) / opts.temperature
        self.say(f"  mcmc: {n} chains x {opts.mcmc_steps} steps, acceptance "
                 f"{float(np.mean(accepted)):.2f}, mean loss {mean_loss:.4g}")
        return np.asarray(tool), np.asarray(desired), np.asarray(props)

    def generator(self, samples: tuple[np.ndarray, np.ndarray, np.ndarray]) -> None:
        """The conditional GAN of Eq. 6-7 on the MCMC samples (non-saturating generator loss)."""
        jax, jnp, opts = self.jax, self.jax.numpy, self.options
        import optax

        tool, desired, props = samples
        cond = np.concatenate([desired / POSITION_SCALE, property_features(props)], axis=-1)
        real = np.concatenate([tool[:, :2] / POSITION_SCALE, np.cos(tool[:, 2:]),
                               np.sin(tool[:, 2:])], axis=-1)
        cond, real = (np.asarray(a, dtype=np.float32) for a in (cond, real))
        c_size = cond.shape[1]
        params = {"generator": self._net(NOISE_SIZE + c_size, 4),
                  "discriminator": self._net(4 + c_size, 1)}

        def fake(g: Any, z: Any, c: Any) -> Any:
            raw = _apply(g, jnp.concatenate([z, c], axis=-1))
            x_r = generator_output(raw, jnp)
            return jnp.concatenate([x_r[:, :2] / POSITION_SCALE, jnp.cos(x_r[:, 2:]),
                                    jnp.sin(x_r[:, 2:])], axis=-1)

        def d_loss(d: Any, g: Any, batch: tuple) -> Any:
            x, c, z = batch
            real_logit = _apply(d, jnp.concatenate([x, c], axis=-1))
            fake_logit = _apply(d, jnp.concatenate([fake(g, z, c), c], axis=-1))
            return jnp.mean(jax.nn.softplus(-real_logit) + jax.nn.softplus(fake_logit))

        def g_loss(g: Any, d: Any, batch: tuple) -> Any:
            _, c, z = batch
            return jnp.mean(jax.nn.softplus(-_apply(d, jnp.concatenate([fake(g, z, c), c], -1))))

        opt_d, opt_g = optax.adam(opts.learning_rate * 0.5, b1=0.5), \
            optax.adam(opts.learning_rate * 0.5, b1=0.5)
        state_d, state_g = opt_d.init(params["discriminator"]), opt_g.init(params["generator"])

        @jax.jit
        def update(d: Any, g: Any, sd: Any, sg: Any, batch: tuple) -> tuple:
            ld, grads = jax.value_and_grad(d_loss)(d, g, batch)
            updates, sd = opt_d.update(grads, sd)
            d = optax.apply_updates(d, updates)
            lg, grads = jax.value_and_grad(g_loss)(g, d, batch)
            updates, sg = opt_g.update(grads, sg)
            return d, optax.apply_updates(g, updates), sd, sg, ld, lg

        start = time.monotonic()
        d, g = params["discriminator"], params["generator"]
        batches = self._batches((real, cond))
        log_d = self._logger("discriminator", opts.gan_steps)
        log_g = self._logger("generator", opts.gan_steps)
        for i in range(opts.gan_steps):
            x, c = batches(i)
            z = self.rng.standard_normal((len(x), NOISE_SIZE)).astype(np.float32)
            d, g, state_d, state_g, ld, lg = update(d, g, state_d, state_g, (x, c, z))
            log_d(i, float(ld))
            log_g(i, float(lg))
        self.params["generator"] = g
        self.seconds["gan"] = time.monotonic() - start

    def run(self, cache: Path | None = None) -> PushData:
        """All four stages (the data read from `cache` if it holds them); the data."""
        self.say(f"data: {self.options.samples} pushes ...")
        data = self.data(cache)
        self.say(f"  {self.seconds.get('data', 0.0):.0f} s")
        self.say("forward models ...")
        self.forward_models(data)
        self.say("policy ...")
        self.policy(data)
        self.say("generator ...")
        self.generator(self.mcmc(data))
        return data

    def save(self, path: str | Path) -> None:
        opts = self.options
        save_models(path, {name: self.params[name] for name in NETWORKS},
                    opts.data.max_speed, opts.data.max_duration, opts.data.reach)

    def report(self) -> dict[str, Any]:
        """The run's options, stage times (s) and loss curves (JSON-ready)."""
        return {"seed": self.seed, "options": asdict(self.options), "seconds": self.seconds,
                "curves": self.curves}


def evaluate(models: Any, data: PushData) -> dict[str, float]:
    """How well the forward models of `models` (`learned_oracle.OracleModels`) predict pushes
    they were not trained on: R² of the mean successor per coordinate (x, y, yaw), R² of x on
    the pushes that moved the object more than 3 cm, and the correlation of the predicted and
    the sampled log variance."""
    mu, var = models.forward(data.tool, data.properties, data.action)
    mean, spread = data.successors.mean(axis=1), data.successors.var(axis=1)
    out: dict[str, float] = {}
    for j, name in enumerate(("x", "y", "yaw")):
        out[f"r2_{name}"] = float(1.0 - np.mean((mu[:, j] - mean[:, j]) ** 2) / mean[:, j].var())
        out[f"log_var_correlation_{name}"] = float(np.corrcoef(np.log(var[:, j] + 1e-8),
                                                               np.log(spread[:, j] + 1e-8))[0, 1])
    moved = np.hypot(mean[:, 0], mean[:, 1]) > 0.03
    out["moved_share"] = float(moved.mean())
    out["r2_x_moved"] = float(1.0 - np.mean((mu[moved, 0] - mean[moved, 0]) ** 2)
                              / mean[moved, 0].var())
    return {k: round(v, 3) for k, v in out.items()}


EVALUATION_SEED = 99
"""The seed of the held-out pushes of --evaluate (training runs use other seeds)."""


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="rearrangement-train",
        description="Train the slice-based RRT's learned oracle (Haustein et al. 2018, §II) for "
                    "the default scene's robot and write it as the .npz the planner reads.")
    parser.add_argument("--seed", type=int, default=0, help="the run's seed (default 0)")
    parser.add_argument("--out", type=Path, default=None,
                        help=f"weights file (default: the shipped {model_path(default_robot())})")
    parser.add_argument("--report", type=Path, default=None,
                        help="write the loss curves and stage times as JSON here, and their "
                             "plot beside it (.png)")
    parser.add_argument("--data", type=Path, default=None,
                        help="keep the simulated pushes in this .npz and reuse them when it "
                             "holds this run's (same seed and options)")
    parser.add_argument("--workers", type=int, default=os.cpu_count() or 1,
                        help="processes simulating the data (default: every core)")
    parser.add_argument("--tiny", action="store_true",
                        help="a few-second run with tiny networks (tests)")
    parser.add_argument("--evaluate", type=Path, metavar="NPZ", default=None,
                        help="train nothing: score the forward models of these weights on "
                             f"3000 fresh pushes (seed {EVALUATION_SEED}) and print JSON")
    args = parser.parse_args(argv)
    if args.evaluate is not None:
        from rearrangement_planner.planning.planners.learned_oracle import load_models

        held_out = generate(3000, EVALUATION_SEED, DataOptions(), workers=args.workers)
        print(json.dumps(evaluate(load_models(args.evaluate), held_out)))
        return 0
    options = TrainOptions.tiny() if args.tiny else TrainOptions()
    started = time.monotonic()
    trainer = Trainer(options, args.seed, workers=args.workers)
    trainer.run(args.data)
    out = args.out or model_path(default_robot())
    trainer.save(out)
    total = time.monotonic() - started
    print(f"wrote {out} ({out.stat().st_size / 1e3:.0f} kB) in {total:.0f} s")
    if args.report is not None:
        from rearrangement_planner.tools.bench.plots import plot_training

        report = trainer.report() | {"total_seconds": total}
        args.report.write_text(json.dumps(report, indent=1))
        print(f"wrote {args.report} and {plot_training(report, args.report.with_suffix('.png'))}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
