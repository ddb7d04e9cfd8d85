"""Temporal ensembling of a diffusion policy's chunks (``eval.ensemble``)."""

from __future__ import annotations

import math
from collections import deque
from types import SimpleNamespace
from typing import Any

import pytest

torch = pytest.importorskip("torch")
pytest.importorskip("lerobot")

from factory.errors import PolicyError
from factory.policy.checkpoint import ENSEMBLE_K, ChunkEnsemble, TrainInfo, resolve_ensemble


class _Chunks:
    """A stand-in for lerobot's DiffusionPolicy that predicts the given chunks in turn."""

    def __init__(self, chunks: list[Any]) -> None:
        self.config = SimpleNamespace(horizon=4, n_obs_steps=2, n_action_steps=2, image_features={})
        self._queues = {"observation.state": deque(maxlen=2), "action": deque(maxlen=2)}
        self._chunks = iter(chunks)
        self.seen: list[int] = []

    def predict_action_chunk(self, batch: dict[str, Any]) -> Any:
        self.seen.append(len(self._queues["observation.state"]))
        return next(self._chunks)


def test_ensemble_averages_the_kept_chunks_oldest_first() -> None:
    # one env, 1-D actions; each chunk predicts 3 frames (horizon 4 - 2 observations + 1)
    a = torch.tensor([[[0.0], [1.0], [2.0]]])
    b = torch.tensor([[[10.0], [11.0], [12.0]]])  # another mode, e.g. the other side of a mug
    c = torch.tensor([[[20.0], [21.0], [22.0]]])
    d = torch.tensor([[[30.0], [31.0], [32.0]]])
    policy = _Chunks([a, b, c, d])
    ens = ChunkEnsemble(policy, k=1.0)
    assert policy.config.n_action_steps == 3  # the whole chunk is kept
    obs = {"observation.state": torch.zeros(1, 5), "action": None}
    w = math.exp(-1.0)
    got = [float(ens.select_action(obs)[0, 0]) for _ in range(4)]
    assert got[0] == pytest.approx(0.0)
    assert got[1] == pytest.approx((1.0 + w * 10.0) / (1 + w))
    assert got[2] == pytest.approx((2.0 + w * 11.0 + w**2 * 20.0) / (1 + w + w**2))
    # a's chunk has ended: b is now the oldest
    assert got[3] == pytest.approx((12.0 + w * 21.0 + w**2 * 30.0) / (1 + w + w**2))
    assert policy.seen == [2, 2, 2, 2]  # observation queues filled as lerobot's select_action
    ens.reset()
    policy._chunks = iter([d])
    assert float(ens.select_action(obs)[0, 0]) == pytest.approx(30.0)


def test_ensemble_every_other_frame_predicts_half_as_often() -> None:
    """``eval.ensemble_every=2``: a chunk on frames 0, 2, 4; every frame the weighted mean of the
    chunks kept, the observation queues filled every frame."""
    a = torch.tensor([[[0.0], [1.0], [2.0]]])
    b = torch.tensor([[[10.0], [11.0], [12.0]]])
    c = torch.tensor([[[20.0], [21.0], [22.0]]])
    policy = _Chunks([a, b, c])
    ens = ChunkEnsemble(policy, k=1.0, every=2)
    obs = {"observation.state": torch.zeros(1, 5), "action": None}
    w = math.exp(-1.0)
    got = [float(ens.select_action(obs)[0, 0]) for _ in range(5)]
    assert got[0] == pytest.approx(0.0)
    assert got[1] == pytest.approx(1.0)  # a alone, no new chunk
    assert got[2] == pytest.approx((2.0 + w * 10.0) / (1 + w))
    assert got[3] == pytest.approx(11.0)  # a has ended
    assert got[4] == pytest.approx((12.0 + w * 20.0) / (1 + w))
    assert len(policy.seen) == 3 and len(policy._queues["observation.state"]) == 2
    with pytest.raises(PolicyError, match="ensemble_every=4"):
        ChunkEnsemble(_Chunks([]), k=0.1, every=4)  # longer than a chunk (3 frames)


def _info(policy_type: str = "diffusion", action: str = "tool") -> TrainInfo:
    return TrainInfo(
        name="p",
        policy_type=policy_type,
        inputs="state",
        dataset="d",
        scenes=["s"],
        episodes=1,
        steps=1,
        fps=20,
        features={"observation.state": [8]},
        action=action,
    )


def test_ensemble_setting_resolves_per_policy() -> None:
    assert resolve_ensemble(None, _info()) == ENSEMBLE_K
    assert resolve_ensemble(None, _info(action="joint")) == ENSEMBLE_K
    assert resolve_ensemble(None, _info(action="tool_rel")) is None
    assert resolve_ensemble(None, _info(policy_type="act")) is None
    assert resolve_ensemble(-1.0, _info()) is None
    assert resolve_ensemble(0.5, _info()) == 0.5
    with pytest.raises(PolicyError, match=r"eval\.ensemble=-1"):
        resolve_ensemble(0.1, _info(action="tool_rel"))


@pytest.mark.parametrize("every", [0, -2, 1.5, True])
def test_ensemble_every_refused(every: Any) -> None:
    from factory.config import EvalConfig
    from factory.errors import ConfigError
    from factory.policy.eval_stage import check_config

    with pytest.raises(ConfigError, match=r"eval\.ensemble_every="):
        check_config(EvalConfig(ensemble_every=every))
    check_config(EvalConfig(ensemble_every=3))
