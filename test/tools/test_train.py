"""The learned oracle's training (Haustein et al. 2018, §II) and its NumPy inference: the data
come from the planner's physics and are reproducible, a tiny run's losses fall, the .npz the
planner reads gives what JAX computed, and the shipped weights run the same in both."""

import jax.numpy as jnp
import numpy as np
import pytest

from rearrangement_planner.planning.planners import learned_oracle as lo
from rearrangement_planner.tools.training import command as train
from rearrangement_planner.tools.training import push_data


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    trainer = train.Trainer(train.TrainOptions.tiny(), seed=3, say=lambda _: None)
    data = trainer.run()
    path = tmp_path_factory.mktemp("oracle") / "tiny.npz"
    trainer.save(path)
    return trainer, data, path


def test_the_data_is_reproducible_and_holds_real_pushes():
    options = push_data.DataOptions(noise_draws=3, arm_states=2)
    a = push_data.generate(40, seed=5, options=options)
    b = push_data.generate(40, seed=5, options=options)
    for name in ("tool", "properties", "action", "successors"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
    assert a.successors.shape == (40, 3, 3) and a.properties.shape == (40, 7)
    # the tool starts outside the object's footprint circle, within reach of it
    footprint = np.where(a.properties[:, 0] > 0.5, 0.5 * a.properties[:, 1],
                         0.5 * np.hypot(a.properties[:, 1], a.properties[:, 2]))
    distance = np.hypot(a.tool[:, 0], a.tool[:, 1]) - footprint
    assert np.all(distance >= 0.0) and np.all(distance <= options.reach)
    # some pushes move the object far beyond the 5 mm pose noise
    assert np.max(np.hypot(*a.successors[:, :, :2].mean(axis=1).T)) > 0.03


def test_a_tiny_run_lowers_its_losses(tiny):
    trainer, _, _ = tiny
    for name in ("forward", "policy"):
        curve = trainer.curves[name]
        assert np.mean(curve[-3:]) < np.mean(curve[:3]), (name, curve[:3], curve[-3:])


def _jax_policy(params, tool, desired, props, speed, duration):
    x = jnp.concatenate([lo.tool_features(tool, jnp), desired / lo.POSITION_SCALE,
                         lo.property_features(props, jnp)], axis=-1)
    return lo.policy_output(lo.mlp(*params, x, jnp), speed, duration, jnp)


def _inputs(n, seed=0):
    rng = np.random.default_rng(seed)
    tool = np.column_stack([rng.uniform(-0.15, 0.15, (n, 2)), rng.uniform(-3, 3, n)])
    desired = rng.uniform(-0.3, 0.3, (n, 2))
    props = np.column_stack([rng.integers(0, 2, n), rng.uniform(0.04, 0.16, (n, 3)),
                             rng.uniform(0.2, 0.8, (n, 3))])
    return tool, desired, props


def test_numpy_inference_of_the_saved_file_equals_jax(tiny):
    trainer, _, path = tiny
    models = lo.load_models(path)
    tool, desired, props = _inputs(50)
    opts = trainer.options.data
    expected = _jax_policy(trainer.params["policy"], jnp.asarray(tool, jnp.float32),
                           jnp.asarray(desired, jnp.float32), jnp.asarray(props, jnp.float32),
                           opts.max_speed, opts.max_duration)
    np.testing.assert_allclose(models.policy(tool, desired, props), np.asarray(expected),
                               rtol=1e-4, atol=1e-5)
    z = np.random.default_rng(1).standard_normal((50, lo.NOISE_SIZE))
    raw = lo.mlp(*trainer.params["generator"], jnp.asarray(
        np.concatenate([z, desired / lo.POSITION_SCALE, lo.property_features(props)], axis=-1),
        jnp.float32), jnp)
    np.testing.assert_allclose(models.generate(z, desired, props),
                               np.asarray(lo.generator_output(raw, jnp)), rtol=1e-4, atol=1e-5)


def test_the_shipped_weights_run_the_same_in_numpy_and_jax(panda):
    models = lo.shipped_models(panda.config.name)
    with np.load(lo.model_path(panda.config.name)) as data:
        layers = sum(1 for k in data.files if k.startswith("policy/w"))
        params = ([jnp.asarray(data[f"policy/w{i}"]) for i in range(layers)],
                  [jnp.asarray(data[f"policy/b{i}"]) for i in range(layers)])
    tool, desired, props = _inputs(100, seed=2)
    expected = _jax_policy(params, *(jnp.asarray(a, jnp.float32) for a in (tool, desired, props)),
                           models.max_speed, models.max_duration)
    np.testing.assert_allclose(models.policy(tool, desired, props), np.asarray(expected),
                               rtol=1e-4, atol=1e-5)
    assert lo.model_path(panda.config.name).stat().st_size < 5e6


def test_a_missing_or_partial_model_file_is_a_clear_error(tmp_path):
    with pytest.raises(FileNotFoundError, match="rearrangement-train"):
        lo.load_models(tmp_path / "none.npz")
    np.savez(tmp_path / "partial.npz", meta=np.array([0.1, 4.0, 0.14]))
    with pytest.raises(ValueError, match="'f_mu' is missing"):
        lo.load_models(tmp_path / "partial.npz")


def test_the_training_command_writes_weights_and_a_report(tmp_path):
    out, report = tmp_path / "w.npz", tmp_path / "r.json"
    assert train.main(["--tiny", "--seed", "1", "--out", str(out), "--report", str(report)]) == 0
    models = lo.load_models(out)
    assert set(models.networks) == set(lo.NETWORKS)
    assert '"curves"' in report.read_text()
    assert report.with_suffix(".png").read_bytes().startswith(b"\x89PNG")


def test_the_states_figure_is_drawn_from_weights(tiny, tmp_path, capsys):
    from rearrangement_planner.tools.bench import command as bench

    _, _, path = tiny
    out = tmp_path / "states.png"
    assert bench.main(["states", "--weights", str(path), "--out", str(out)]) == 0
    assert out.read_bytes().startswith(b"\x89PNG") and out.stat().st_size > 20000
    assert bench.main(["states", "--weights", str(tmp_path / "none.npz")]) == 2
    assert "--weights: no learned oracle at" in capsys.readouterr().err


def test_evaluation_scores_the_forward_models_on_held_out_pushes(tiny):
    _, data, path = tiny
    scores = train.evaluate(lo.load_models(path), data)
    assert {"r2_x", "r2_y", "r2_yaw", "r2_x_moved", "moved_share"} <= set(scores)
    # models that predict each push's mean successor exactly score R² = 1
    exact = train.evaluate(_Exact(data.successors.mean(axis=1)), data)
    assert exact["r2_x"] == exact["r2_y"] == exact["r2_yaw"] == 1.0


class _Exact:
    """Stands in for the models: forward() returns the data's own mean successor."""

    def __init__(self, mean):
        self.mean = mean

    def forward(self, tool, props, action):
        return self.mean, np.full_like(self.mean, 1e-4)
