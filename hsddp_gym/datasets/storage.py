"""Writing and reading datasets: the Minari dataset, episodes.npz, metadata.json, atomic publishing."""

from __future__ import annotations

import contextlib
import dataclasses
import json
import os
import re
import shutil
import tempfile
from pathlib import Path

import numpy as np

from hsddp_gym.datasets.recording import ENV_ID, Episode
from hsddp_gym.registry import TASKS, task_of_env_id
from hsddp_gym.util.io import json_default, read_npz, write_json, write_npz


# ================================================================================================ writing
@contextlib.contextmanager
def minari_root(path):
    """Set ``MINARI_DATASETS_PATH`` to ``path`` for the duration of the block (restored after)."""
    old = os.environ.get("MINARI_DATASETS_PATH")
    os.environ["MINARI_DATASETS_PATH"] = str(path)
    try:
        yield Path(path)
    finally:
        if old is None:
            os.environ.pop("MINARI_DATASETS_PATH", None)
        else:
            os.environ["MINARI_DATASETS_PATH"] = old


def default_dataset_id(policy_name: str, env_id: str | None = None) -> str:
    """``hsddp_gym/<task>/<policy>-v0`` with ``<task>`` the name of ``env_id``'s task in the registry
    ([`hsddp_gym.registry.TASKS`][hsddp_gym.registry.TASKS]; ``env_id`` None: Bounding-v0's, ``bounding``), e.g.
    ``hsddp_gym/pronking/expert-v0`` for ``hsddp_gym/Pronking-v0``; ``ValueError`` for an env of no task."""
    task = TASKS["bounding"] if env_id is None else task_of_env_id(env_id)
    return f"hsddp_gym/{task.name}/{policy_name}-v0"


def episodes_to_arrays(episodes: list[Episode]) -> dict:
    """Flat arrays of ``episodes`` (the ``episodes.npz`` layout, see [`load_npz`][load_npz])."""
    lengths = np.array([e.length for e in episodes], dtype=np.int64)
    arrays = {
        "observations": np.concatenate([e.observations for e in episodes]),
        "actions": np.concatenate([e.actions for e in episodes]),
        "rewards": np.concatenate([e.rewards for e in episodes]),
        "terminations": np.concatenate([e.terminations for e in episodes]),
        "truncations": np.concatenate([e.truncations for e in episodes]),
        "episode_starts": np.concatenate([[0], np.cumsum(lengths)]).astype(np.int64),
        "observation_starts": np.concatenate([[0], np.cumsum(lengths + 1)]).astype(np.int64),
        "episode_lengths": lengths,
        "episode_seeds": np.array([e.seed for e in episodes], dtype=np.int64),
        "episode_returns": np.array([e.episode_return for e in episodes]),
    }
    for k in episodes[0].infos:
        arrays[f"infos/{k}"] = np.concatenate([e.infos[k] for e in episodes])
    return arrays


def write_dataset(episodes: list[Episode], out, dataset_id: str, env, metadata: dict, *,
                  ref_min_score: float, ref_max_score: float, overwrite: bool = False,
                  extra_files: dict | None = None, description: str | None = None,
                  algorithm_name: str = "hsddp_gym") -> Path:
    """Write ``episodes`` as a Minari dataset + ``episodes.npz`` + ``metadata.json`` into ``out`` atomically.

    Args:
        env: the ``gym.make``'d env the episodes were recorded in (its spec, with the kwargs and time
            limit, is stored so that ``recover_environment()`` rebuilds it).
        metadata: JSON-serializable; stored in ``metadata.json``, in the npz and in Minari's metadata.
        extra_files: ``{name: existing path}`` copied into the dataset directory.
    Raises:
        FileExistsError: ``out`` exists and ``overwrite`` is False.
    """
    out = Path(out)
    check_target(out, overwrite)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.tmp-", dir=parent_dir(out)))
    try:
        _write_into(tmp, episodes, dataset_id, env, metadata, ref_min_score, ref_max_score, extra_files,
                    description, algorithm_name)
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o777 & ~umask)  # mkdtemp creates 0700; the published dataset gets the usual permissions
        _publish(tmp, out, overwrite)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return out


def parent_dir(out: Path) -> Path:
    parent = out.resolve().parent
    parent.mkdir(parents=True, exist_ok=True)
    return parent


def check_target(out: Path, overwrite: bool) -> None:
    if out.exists() and not overwrite:
        raise FileExistsError(f"{out} already exists; pass overwrite=True (CLI: --overwrite) to replace it")
    if out.exists() and not out.is_dir():
        raise FileExistsError(f"{out} exists and is not a directory")


def _publish(tmp: Path, out: Path, overwrite: bool) -> None:
    if out.exists():
        if not overwrite:
            raise FileExistsError(f"{out} already exists; pass overwrite=True (CLI: --overwrite) to replace it")
        trash = Path(tempfile.mkdtemp(prefix=f".{out.name}.old-", dir=out.resolve().parent))
        os.rename(out, trash / "old")
        try:
            os.rename(tmp, out)
        except BaseException:
            os.rename(trash / "old", out)
            raise
        finally:
            shutil.rmtree(trash, ignore_errors=True)
    else:
        os.rename(tmp, out)


def _write_into(tmp: Path, episodes, dataset_id, env, metadata, ref_min_score, ref_max_score, extra_files,
                description, algorithm_name) -> None:
    import warnings

    import minari
    from minari.data_collector import EpisodeBuffer

    for name, src in (extra_files or {}).items():
        shutil.copy2(str(src), tmp / name)  # copied: the source stays valid if this write fails
    buffers = [EpisodeBuffer(id=i, seed=e.seed, observations=e.observations, actions=e.actions,
                             rewards=e.rewards, terminations=e.terminations, truncations=e.truncations,
                             infos={k: v for k, v in e.infos.items()}) for i, e in enumerate(episodes)]
    with minari_root(tmp / "minari"), warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=".*(author|author_email|code_permalink|eval_env).*")
        ds = minari.create_dataset_from_buffers(
            dataset_id, buffers, env=env, algorithm_name=algorithm_name, author="hsddp_gym",
            author_email="n/a", code_permalink="https://github.com/ (hsddp_gym, see metadata)",
            ref_min_score=float(ref_min_score), ref_max_score=float(ref_max_score),
            description=description or f"{metadata.get('policy', {}).get('name', '?')} demonstrations on {ENV_ID}",
            requirements=None)
        ds.storage.update_metadata({"hsddp_gym": json.loads(json.dumps(metadata, default=json_default))})
    arrays = episodes_to_arrays(episodes)
    arrays["metadata"] = np.array(json.dumps(metadata, default=json_default))
    write_npz(tmp / "episodes.npz", **arrays)
    write_json(tmp / "metadata.json", metadata)


def package_version() -> str:
    import hsddp_gym

    return getattr(hsddp_gym, "__version__", "unknown")


# ================================================================================================ loading
DATASET_FILES = ("metadata.json", "episodes.npz", "minari")
"""What a dataset directory written by [`write_dataset`][write_dataset] holds."""
_DATASET_ALLOWED = ("a dataset directory holding metadata.json, episodes.npz and minari/, written by `hsddp-gym "
                    "dataset --out DIR` or hsddp_gym.datasets.generate_dataset")


def resolve_dataset_dir(path, name: str = "path") -> Path:
    """The dataset directory that ``path`` names: the directory itself, or one of its parts (``DIR/minari``,
    ``DIR/episodes.npz``, ``DIR/metadata.json``, or a folder inside ``DIR/minari``), which resolve to ``DIR``.

    Raises:
        UsageError: a ValueError naming ``name``: ``path`` does not exist or is no dataset directory.
    """
    from hsddp_gym.util.validation import UsageError

    path = Path(path)
    if not path.exists():
        raise UsageError(name, f"{str(path)!r} does not exist", _DATASET_ALLOWED)
    for candidate in (path, *path.parents):
        if (candidate / "metadata.json").is_file() and (candidate / "episodes.npz").is_file():
            if candidate == path or path.is_relative_to(candidate / "minari") \
                    or (path.parent == candidate and path.name in DATASET_FILES):
                return candidate
            break
    raise UsageError(name, f"{str(path)!r} is not a dataset directory (no metadata.json and episodes.npz)",
                     _DATASET_ALLOWED)


_DATASET_ID_RE = re.compile(r"(?:[-_\w][-_\w/]*[-_\w]+/)?[-_\w]+?-v\d+")


def check_dataset_id(dataset_id: str, name: str = "dataset_id") -> str:
    """A Minari dataset id ``(namespace/)name-vVERSION`` (the version is required), or
    [`UsageError`][hsddp_gym.util.validation.UsageError]."""
    from hsddp_gym.util.validation import UsageError

    if not isinstance(dataset_id, str) or not _DATASET_ID_RE.fullmatch(dataset_id):
        raise UsageError(name, f"malformed dataset id {dataset_id!r}",
                         "(namespace/)name-vVERSION of letters, digits, '-' and '_', e.g. "
                         "hsddp_gym/bounding/mpc-v0")
    return dataset_id


def read_metadata(path) -> dict:
    """The ``metadata.json`` of a dataset directory (or of the dataset ``path`` lies in, see
    [`resolve_dataset_dir`][resolve_dataset_dir])."""
    return json.loads((resolve_dataset_dir(path) / "metadata.json").read_text())


def load_minari(path, dataset_id: str | None = None):
    """``minari.load_dataset`` of the dataset in directory ``path`` (``MINARI_DATASETS_PATH`` is set to
    ``path/minari`` for the call only; the returned dataset keeps reading from there). ``path`` may also
    name the dataset's ``minari/`` folder (see [`resolve_dataset_dir`][resolve_dataset_dir]).

    Raises:
        UsageError: a ValueError naming ``path``: ``path`` does not exist or is no dataset directory, as
            [`load_npz`][load_npz].
    """
    from hsddp_gym.util.extras import require

    require(["minari", "h5py"], "load_minari")
    import minari

    path = resolve_dataset_dir(path)
    dataset_id = dataset_id or read_metadata(path)["dataset_id"]
    with minari_root(path / "minari"):
        return minari.load_dataset(dataset_id)


@dataclasses.dataclass
class FlatDataset:
    """The ``episodes.npz`` of a dataset: flat arrays and episode boundaries.

    ``observations (sum(T_i + 1), d)`` (each episode's T_i + 1 rows, episode i from
    ``observation_starts[i]``), ``actions / rewards / terminations / truncations (sum T_i, ...)`` (episode i
    from ``episode_starts[i]``), ``infos`` {key: (sum(T_i + 1), ...)} aligned with the observations.
    """

    observations: np.ndarray
    actions: np.ndarray
    rewards: np.ndarray
    terminations: np.ndarray
    truncations: np.ndarray
    episode_starts: np.ndarray
    observation_starts: np.ndarray
    episode_seeds: np.ndarray
    infos: dict
    metadata: dict

    @property
    def n_episodes(self) -> int:
        return int(len(self.episode_starts) - 1)

    def episode(self, i: int) -> dict:
        """Episode ``i`` as a dict with the Minari field names."""
        a, b = self.episode_starts[i], self.episode_starts[i + 1]
        oa, ob = self.observation_starts[i], self.observation_starts[i + 1]
        return {"observations": self.observations[oa:ob], "actions": self.actions[a:b], "rewards": self.rewards[a:b],
                "terminations": self.terminations[a:b], "truncations": self.truncations[a:b],
                "infos": {k: v[oa:ob] for k, v in self.infos.items()}, "seed": int(self.episode_seeds[i])}

    def transitions(self) -> tuple[np.ndarray, np.ndarray]:
        """``(obs (N, d), actions (N, 4))``: the observation each action was taken at."""
        keep = np.ones(len(self.observations), dtype=bool)
        keep[self.observation_starts[1:] - 1] = False  # the final observation of each episode
        return self.observations[keep], self.actions


def load_npz(path) -> FlatDataset:
    """Read ``episodes.npz`` (``path`` is the dataset directory, one of its parts, see
    [`resolve_dataset_dir`][resolve_dataset_dir], or an ``episodes.npz`` file itself); never unpickles.

    Raises:
        UsageError: a ValueError naming ``path``: ``path`` does not exist or is no dataset directory, as
            [`load_minari`][load_minari].
    """
    path = Path(path)
    d = read_npz(path if path.is_file() and path.suffix == ".npz" else resolve_dataset_dir(path) / "episodes.npz")
    infos = {k[len("infos/"):]: v for k, v in d.items() if k.startswith("infos/")}
    return FlatDataset(observations=d["observations"], actions=d["actions"], rewards=d["rewards"],
                       terminations=d["terminations"], truncations=d["truncations"],
                       episode_starts=d["episode_starts"], observation_starts=d["observation_starts"],
                       episode_seeds=d["episode_seeds"], infos=infos, metadata=json.loads(str(d["metadata"])))
