"""A training run's settings and folder: the algorithms' defaults, their ranges, the run's config.

Settings are data: :data:`PPO_DEFAULTS` and :data:`BC_DEFAULTS` (``hyperparams/ppo.yml``
holds PPO's per task in the RL Baselines3 Zoo format), each checked against
:data:`SETTING_RANGES` when a :class:`TrainConfig` is made, so that a bad value is
refused by name before any network is built. A run's folder (its record, models and
checkpoints) is read here too, to check a resume before anything trains. Importing this
module does not import torch or stable-baselines3 (:mod:`baselines.rl` trains).
"""

from __future__ import annotations

import ast
import json
import math
import re
import shutil
import zipfile
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TypeGuard

import yaml

from humotion_gym.checks import check_count, is_real
from humotion_gym.envs import get_task
from humotion_gym.mocap.library import configured_data_dirs

ALGOS: tuple[str, ...] = ("ppo", "bc")

#: PPO settings used when no hyperparameter file is given (``hyperparams/ppo.yml``
#: holds the same values per task in the RL Baselines3 Zoo format; a test checks
#: that they agree).
PPO_DEFAULTS: dict[str, Any] = {
    "n_envs": 8,
    "n_steps": 128,
    "batch_size": 256,
    "n_epochs": 4,
    "learning_rate": 3e-4,
    "gamma": 0.9,
    "gae_lambda": 0.9,
    "clip_range": 0.2,
    "ent_coef": 0.0,
    "vf_coef": 0.5,
    "max_grad_norm": 0.5,
    "log_std_init": -2.5,
    "features_dim": 128,
    "frame_size": 64,
}

#: Behaviour-cloning settings (see :func:`train_bc`).
BC_DEFAULTS: dict[str, Any] = {
    "n_envs": 8,
    "rounds": 8,
    "batch_size": 128,
    "learning_rate": 1e-3,
    "passes": 16.0,
    "buffer_size": 40_000,
    "expert_noise": 0.08,
    "features_dim": 128,
    "frame_size": 64,
}


@dataclass
class TrainConfig:
    """Everything a training run needs, saved as ``config.json`` beside the model.

    Attributes:
        algo: ``"ppo"`` or ``"bc"``.
        task: Task id, e.g. ``"BodyTrack-v2"``.
        steps: Environment steps to train for.
        seed: Seed of the policy, the episodes and the rollouts.
        out: Output folder (``model.zip``, ``config.json``, ``checkpoints/``).
        data_dir: Motion capture folders (None: ``$HUMOTION_MOCAP``'s, else the
            synthetic library; ``config.json`` records :func:`run_data_dirs`).
        settings: Algorithm settings (:data:`PPO_DEFAULTS`/:data:`BC_DEFAULTS`
            overridden by the hyperparameter file and the caller).
        init: A saved policy to start from (PPO fine-tuning from ``bc``).
        checkpoint_every: Save a checkpoint every this many env steps (PPO: at
            the first end of an update at or past each multiple).
        threads: Torch threads.
        validation: Track the validation persons
            (:func:`baselines.experiments.selection.validation_library`, never
            trained on) every ``eval_every`` env steps and at the end, logged
            as ``eval/mean_error_mm``.
        eval_every: Env steps between two validation runs.
        eval_episodes: Validation episodes per run.
    """

    algo: str
    task: str
    steps: int
    seed: int = 0
    out: str = "runs/run"
    data_dir: list[str] | None = None
    settings: dict[str, Any] = field(default_factory=dict)
    init: str | None = None
    checkpoint_every: int = 10_000
    threads: int = 1
    validation: bool = True
    eval_every: int = 10_000
    eval_episodes: int = 5

    def __post_init__(self) -> None:
        if self.algo not in ALGOS:
            raise ValueError(f"algo: expected one of {list(ALGOS)}, got {self.algo!r}")
        spec = get_task(self.task)
        if spec.views > 1:  # its name is the one-view task's: training would drop the views
            raise ValueError(
                f"task: {self.task} shows {spec.views} views; the learned policies read one "
                f"camera's frame (LearnerObservation), so train on {spec.name}"
            )
        self.task = spec.name
        check_count("steps", self.steps)
        for name in ("checkpoint_every", "eval_every", "eval_episodes"):
            if getattr(self, name) < 1:
                raise ValueError(f"{name}: expected >= 1, got {getattr(self, name)}")
        defaults = PPO_DEFAULTS if self.algo == "ppo" else BC_DEFAULTS
        unknown = sorted(set(self.settings) - set(defaults))
        if unknown:
            raise ValueError(
                f"{self.algo} settings: unknown {unknown}; the settings are {sorted(defaults)}"
            )
        self.settings = {**defaults, **self.settings}
        for name, value in self.settings.items():
            _check_setting(name, value)
        # A count written 64.0 (YAML, --set) is 64: the networks and buffers take ints.
        self.settings = {
            name: int(value) if SETTING_RANGES[name][0] else value
            for name, value in self.settings.items()
        }
        s = self.settings
        if self.algo == "ppo" and s["batch_size"] > s["n_steps"] * s["n_envs"]:
            raise ValueError(
                f"setting batch_size: {s['batch_size']} is more than a rollout's "
                f"n_steps * n_envs = {s['n_steps'] * s['n_envs']} env steps"
            )


#: Each setting's kind and range: ``(integer, lowest, highest)``, both ends
#: taken; ``lowest`` None: any finite number. A count is at least 1, a rate
#: above 0; PPO splits ``n_steps * n_envs`` into batches of at least 2. A frame
#: of at least 17 pixels leaves the policy's three strided convolutions
#: (:class:`~baselines.agents.policy.TrackingExtractor`: 5x5, 3x3, 3x3, stride
#: 2) at least one pixel.
SETTING_RANGES: dict[str, tuple[bool, float | None, float]] = {
    "n_envs": (True, 1, 4096),
    "n_steps": (True, 2, 1e7),
    "batch_size": (True, 2, 1e7),
    "n_epochs": (True, 1, 1e4),
    "rounds": (True, 1, 1e6),
    "buffer_size": (True, 1, 1e8),
    "features_dim": (True, 1, 1e5),
    "frame_size": (True, 17, 640),
    "learning_rate": (False, 1e-12, 10.0),
    "gamma": (False, 0.0, 1.0),
    "gae_lambda": (False, 0.0, 1.0),
    "clip_range": (False, 1e-12, 1e6),
    "ent_coef": (False, 0.0, 1e6),
    "vf_coef": (False, 0.0, 1e6),
    "max_grad_norm": (False, 1e-12, 1e6),
    "log_std_init": (False, None, 1e6),
    "passes": (False, 1e-12, 1e6),
    "expert_noise": (False, 0.0, 1e6),
}


def _check_setting(name: str, value: Any) -> None:
    """Refuse a training setting outside :data:`SETTING_RANGES`, naming it."""
    integer, low, high = SETTING_RANGES[name]
    ok = is_real(value) and math.isfinite(value) and (low is None or low <= value) and value <= high
    if integer:
        ok = ok and float(value).is_integer()
    if not ok:
        kind = "an integer" if integer else "a number"
        shown = [f"{int(v):,}" if integer else f"{v:g}" for v in (low or 0, high)]
        where = f"from {shown[0]} to {shown[1]}" if low is not None else f"up to {shown[1]}"
        raise ValueError(f"setting {name}: expected {kind} {where}, got {value!r}")


#: What ``humotion-gym train`` builds whatever a zoo entry says: the entry must say the
#: same (``policy``, ``env_kwargs``) or leave it out. ``n_timesteps`` is the zoo's;
#: ``train`` runs ``--steps``.
ZOO_FIXED: dict[str, Any] = {
    "policy": "MultiInputPolicy",
    "env_kwargs": {"split": "train", "terminate_on_lost": False},
}
ZOO_IGNORED: tuple[str, ...] = ("n_timesteps",)
#: The one ``env_wrapper`` of a zoo entry: the learners' observation, its ``size`` read.
LEARNER_WRAPPER = "humotion_gym.wrappers.LearnerObservation"
#: Every learned tracker's network heads (:func:`baselines.agents.policy.policy_kwargs`):
#: an empty policy net, so the action layer reads the features directly and can copy
#: the estimate the extractor passes on; a value net of 64.
POLICY_NET_ARCH: dict[str, list[int]] = {"pi": [], "vf": [64]}
#: ``policy_kwargs`` as ``train`` builds it (:func:`baselines.agents.policy.policy_kwargs`).
ZOO_POLICY_FIXED: dict[str, Any] = {"net_arch": POLICY_NET_ARCH, "normalize_images": False}


def load_hyperparams(path: str | Path, task: str) -> dict[str, Any]:
    """PPO settings of one task from an RL Baselines3 Zoo YAML file.

    Reads the entry ``humotion_gym/TASK`` (or ``TASK``): ``n_envs``,
    ``n_steps``, ``batch_size``, ``n_epochs``, ``learning_rate``, ``gamma``,
    ``gae_lambda``, ``clip_range``, ``ent_coef``, ``vf_coef``,
    ``max_grad_norm``; ``log_std_init`` and ``features_dim`` from the
    ``policy_kwargs`` string; ``frame_size`` from the ``env_wrapper``'s
    ``size``. Every other key must be one ``train`` honours as the entry
    says (:data:`ZOO_FIXED`, :data:`ZOO_POLICY_FIXED`) or ignores by design
    (:data:`ZOO_IGNORED`), so that no setting is dropped in silence.

    Raises:
        ValueError: Naming the file and entry: no entry for the task, an entry
            that is not a mapping, a key ``train`` would not honour, or a value
            out of its range (:data:`SETTING_RANGES`).
    """
    name = get_task(task).name
    data = _read_zoo_yaml(Path(path))
    key = f"humotion_gym/{name}" if f"humotion_gym/{name}" in data else name
    entry = data.get(key)
    where = f"{path}: {key}"
    if entry is None:
        raise ValueError(f"{path}: no entry humotion_gym/{name}")
    if not isinstance(entry, dict):
        raise ValueError(f"{where}: expected a mapping of settings, got {entry!r}")
    read = set(PPO_DEFAULTS) - {"log_std_init", "features_dim", "frame_size"}
    unknown = sorted(set(entry) - read - set(ZOO_FIXED) - set(ZOO_IGNORED)
                     - {"policy_kwargs", "env_wrapper"})  # fmt: skip
    if unknown:
        raise ValueError(
            f"{where}: humotion-gym train does not use {unknown}; remove them (or train with "
            f"rl_zoo3); it reads {sorted(read | {'policy_kwargs', 'env_wrapper'})}"
        )
    for fixed, value in ZOO_FIXED.items():
        if fixed in entry and entry[fixed] != value:
            raise ValueError(f"{where}: {fixed} must be {value!r} (what train builds), got "
                             f"{entry[fixed]!r}")  # fmt: skip
    out = {k: entry[k] for k in sorted(read) if k in entry}
    out |= _zoo_policy_kwargs(entry.get("policy_kwargs"), where)
    wrappers = entry.get("env_wrapper") or []
    for wrapper in wrappers:
        kwargs = wrapper.get(LEARNER_WRAPPER) if isinstance(wrapper, dict) else None
        # one wrapper: rl_zoo3 would wrap with each one listed (LearnerObservation twice)
        alone = isinstance(wrapper, dict) and len(wrapper) == len(wrappers) == 1
        if not (alone and isinstance(kwargs, dict)) or set(kwargs) - {"size"}:
            raise ValueError(
                f"{where}: env_wrapper must be [{LEARNER_WRAPPER}: {{size: N}}], one wrapper "
                f"(what train builds), got {entry['env_wrapper']!r}"
            )
        out["frame_size"] = kwargs.get("size", PPO_DEFAULTS["frame_size"])
    for setting, value in out.items():
        try:
            _check_setting(setting, value)
        except ValueError as exc:
            raise ValueError(f"{where}: {exc}") from None
    return out


def _zoo_policy_kwargs(text: Any, where: str) -> dict[str, Any]:
    """``log_std_init`` and ``features_dim`` of a zoo ``policy_kwargs`` string, the rest checked.

    The string is parsed as a ``dict(...)`` call, never run.
    """
    if text is None:
        return {}
    try:
        call = ast.parse(str(text), mode="eval").body
        if not _is_dict_call(call):
            raise SyntaxError("not dict(NAME=VALUE, ...)")
        kwargs = {k.arg: k.value for k in call.keywords if k.arg is not None}
        out: dict[str, Any] = {}
        for name, node in kwargs.items():
            if name == "features_extractor_class":
                if not ast.unparse(node).endswith("TrackingExtractor"):
                    raise ValueError(
                        "features_extractor_class must be baselines.rl.TrackingExtractor"
                    )
            elif name == "features_extractor_kwargs":
                if not (_is_dict_call(node) and [k.arg for k in node.keywords] == ["features_dim"]):
                    raise ValueError("features_extractor_kwargs must be dict(features_dim=N)")
                out["features_dim"] = _literal(node.keywords[0].value)
            elif name == "log_std_init":
                out["log_std_init"] = _literal(node)
            elif name in ZOO_POLICY_FIXED:
                value = _literal(node)
                if value != ZOO_POLICY_FIXED[name]:
                    raise ValueError(f"{name} must be {ZOO_POLICY_FIXED[name]!r} (what train "
                                     f"builds), got {value!r}")  # fmt: skip
            else:
                raise ValueError(f"humotion-gym train does not use {name!r}")
    except (SyntaxError, ValueError) as exc:
        raise ValueError(f"{where}: policy_kwargs: {exc}") from None
    return out


def _is_dict_call(node: ast.expr) -> TypeGuard[ast.Call]:
    """Whether ``node`` is ``dict(NAME=VALUE, ...)``: keywords only, none of them ``**``."""
    return (
        isinstance(node, ast.Call) and ast.unparse(node.func) == "dict" and not node.args
        and all(k.arg is not None for k in node.keywords)
    )  # fmt: skip


def _literal(node: ast.expr) -> Any:
    """A literal, with ``dict(a=...)`` read as ``{"a": ...}`` (ValueError quoting any other)."""
    if _is_dict_call(node):
        return {k.arg: _literal(k.value) for k in node.keywords}
    try:
        return ast.literal_eval(node)
    except ValueError:
        raise ValueError(f"expected a number or other literal, got {ast.unparse(node)!r}") from None


def _read_zoo_yaml(path: Path) -> dict[str, Any]:
    """The entries of a zoo hyperparameter file (ValueError naming it if it is not YAML text)."""
    try:
        data = yaml.safe_load(path.read_text(encoding="utf-8"))
    except UnicodeDecodeError as exc:
        raise ValueError(
            f"{path}: not a YAML text file (byte {exc.start} is not UTF-8 text)"
        ) from None
    except yaml.YAMLError as exc:
        raise ValueError(f"{path}: not a YAML hyperparameter file ({exc})") from None
    return data if isinstance(data, dict) else {}


#: What a resumed run must share with the run it continues, besides every algorithm
#: setting: it is the same run, longer (``steps``, the checkpoint and validation
#: cadence and the threads may change).
RESUME_KEYS: tuple[str, ...] = ("algo", "task", "seed", "data_dir", "init", "validation")

#: The settings a resumed run may change: ``bc``'s rounds split a longer run anew.
RESUME_FREE_SETTINGS: tuple[str, ...] = ("rounds",)


class ResumeMismatch(ValueError):
    """The run asked to resume is another run, an unknown one or none (exit 2 on the CLI)."""


class InitMismatch(ValueError):
    """The policy a run starts from (``--init``) has another network (exit 2 on the CLI)."""


def run_data_dirs(data_dir: Sequence[str | Path] | None) -> list[str]:
    """The motion capture folders a run given ``data_dir`` reads, absolute; [] for synthetic.

    As :func:`~humotion_gym.mocap.library.configured_data_dirs` resolves them
    (``$HUMOTION_MOCAP``'s where ``data_dir`` is None); a run's record keeps them.
    """
    return [str(p.expanduser().resolve()) for p in configured_data_dirs(data_dir)]


def _comparable(key: str, value: Any) -> Any:
    """A recorded value as a resume compares it: paths resolved, so that spellings agree.

    A ``data_dir`` of null (an older record, of ``--data-dir`` folders only) is
    taken for the built-in synthetic library.
    """
    if key == "data_dir":
        return [] if value is None else run_data_dirs(value)
    if key == "init" and isinstance(value, str):
        return str(Path(value).expanduser().resolve())
    return value


def read_record(path: Path) -> dict[str, Any]:
    """A run's record, its ``config.json``.

    Raises:
        ValueError: If it is not a JSON object (the message names the file).
    """
    try:
        saved = json.loads(path.read_text(encoding="utf-8"))
    except ValueError as exc:
        raise ValueError(f"{path}: not a run's record ({exc})") from None
    if not isinstance(saved, dict):
        raise ValueError(f"{path}: not a run's record (a JSON object)")
    return saved


def resume_differences(saved: dict[str, Any], config: TrainConfig) -> list[str]:
    """``"KEY: saved A, now B"`` for each of :data:`RESUME_KEYS` and the settings that differ.

    Only the run's length (with :data:`RESUME_FREE_SETTINGS`) and how often it
    checkpoints and validates may differ in a resumed run.
    """
    now = {key: _comparable(key, getattr(config, key)) for key in RESUME_KEYS}
    now["data_dir"] = run_data_dirs(config.data_dir)  # what it would read: $HUMOTION_MOCAP too
    before = {key: _comparable(key, saved.get(key)) for key in RESUME_KEYS}
    recorded = saved.get("settings")
    settings: dict[str, Any] = recorded if isinstance(recorded, dict) else {}
    for key in sorted((set(config.settings) | set(settings)) - set(RESUME_FREE_SETTINGS)):
        now[f"setting {key}"] = config.settings.get(key)
        before[f"setting {key}"] = settings.get(key)
    return [
        f"{k}: saved {_shown(before[k])}, now {_shown(now[k])}" for k in now if before[k] != now[k]
    ]


def _shown(value: Any) -> str:
    """A compared value as a message shows it, the synthetic library (no folder) in words."""
    return "[] (the built-in synthetic library)" if value == [] else repr(value)


def longer_recorded(saved: dict[str, Any], config: TrainConfig) -> int | None:
    """The env steps the recorded run ``saved`` asked for, where more than ``config``'s."""
    asked = saved.get("steps")
    return asked if isinstance(asked, int) and asked > config.steps else None


def check_resumed(path: Path, config: TrainConfig) -> None:
    """Refuse to resume the run recorded in ``path`` as another run (:func:`resume_differences`).

    Raises:
        ValueError: If ``path`` is not a run's record.
        ResumeMismatch: Naming every field that differs.
    """
    try:
        saved = read_record(path)
    except ValueError as exc:
        raise ValueError(f"{exc}; --force starts afresh") from None
    # a missing "init" or "data_dir" reads as none and the synthetic library, as before
    unrecorded = [k for k in RESUME_KEYS if k not in saved and k not in ("init", "data_dir")]
    if unrecorded:  # a record older than the field: no flag can give "the same" run
        raise ResumeMismatch(
            f"--resume: {path.parent}'s record predates {', '.join(unrecorded)}, so no run "
            "can be told to be the same one; start a new run (--force or another --out), "
            f"with --init {path.parent / 'model.zip'} to start from its policy"
        )
    differ = resume_differences(saved, config)
    if differ:
        raise ResumeMismatch(
            f"--resume: {path.parent} holds another run ({'; '.join(differ)}); resume it with "
            "the same settings, or start afresh (--force or another --out)"
        )
    asked = longer_recorded(saved, config)
    if asked is not None:  # its record would say it ran fewer
        raise ResumeMismatch(
            f"--steps {config.steps}: {path.parent} holds a run of {asked:,} env steps; a "
            f"resumed run is the same run, longer: give --steps {asked} or more"
        )


#: What a training run writes into its folder (:func:`baselines.rl.train`).
RUN_NAMES: tuple[str, ...] = ("config.json", "model.zip", "checkpoints", "logs", "tb")


def checkpoints(folder: Path) -> list[tuple[int, Path]]:
    """The run's checkpoints ``model_N_steps.zip`` as ``(N, path)``, fewest steps first."""
    found = []
    for path in folder.glob("model_*_steps.zip"):
        try:
            found.append((int(path.stem.split("_")[1]), path))
        except (IndexError, ValueError):
            continue
    return sorted(found)


def earlier_models(out: Path) -> list[Path]:
    """An earlier run's models in ``out``: its ``model.zip``, then its checkpoints."""
    final = [out / "model.zip"] if (out / "model.zip").is_file() else []
    return final + [p for _, p in checkpoints(out / "checkpoints")]


#: A policy ``train --export`` writes (``bc-ArmTrack-v2.zip`` and its ``.json``).
EXPORT_NAME = re.compile(rf"(?:{'|'.join(ALGOS)})-[A-Za-z0-9]+-v\d+\.(?:zip|json)")


def _training_output(path: Path) -> bool:
    """Whether ``path`` is a training run's: :data:`RUN_NAMES`, an export or a folder of them."""
    if path.name in RUN_NAMES or EXPORT_NAME.fullmatch(path.name):
        return True
    return (
        path.is_dir()
        and any(path.iterdir())
        and all(EXPORT_NAME.fullmatch(p.name) or p.name.startswith(".") for p in path.iterdir())
    )


def foreign_names(out: Path) -> list[str]:
    """What ``out`` holds that no training run writes, at most 3 (hidden names left out)."""
    if not out.is_dir():
        return []
    names = sorted(p.name for p in out.iterdir()
                   if not (_training_output(p) or p.name.startswith(".")))  # fmt: skip
    return names[:3] + ["..."] if len(names) > 3 else names


def _model_steps(path: Path) -> int | None:
    """The env steps a saved model was trained for (its ``num_timesteps``), None if unreadable."""
    try:
        with zipfile.ZipFile(path) as archive:
            steps = json.loads(archive.read("data")).get("num_timesteps")
    except (OSError, KeyError, ValueError, zipfile.BadZipFile, AttributeError):
        return None
    return steps if isinstance(steps, int) and steps >= 0 else None


def resume_point(out: Path) -> tuple[int, Path] | None:
    """Where a resumed run continues: ``(env steps, model file)``, None to start afresh.

    The latest of the run's checkpoints and its final ``model.zip`` (which a
    run that ended after its last checkpoint, or wrote none, holds alone).

    Raises:
        ValueError: If ``model.zip`` is unreadable and there is no checkpoint:
            a resume would start afresh over it (the message names no flag:
            each command says what to do).
    """
    found = checkpoints(out / "checkpoints")
    final = out / "model.zip"
    steps = _model_steps(final) if final.is_file() else None
    if steps is not None and (not found or steps > found[-1][0]):
        return steps, final
    if final.is_file() and steps is None and not found:
        raise ValueError(f"{final} is unreadable and no checkpoint is left to continue from")
    return found[-1] if found else None


def finished_steps(out: Path, steps: int) -> int | None:
    """The env steps of the finished run in ``out`` where they are ``steps`` or more, else None.

    Finished: its final ``model.zip`` is its latest model and its record says
    it ended there (``env_steps``, written last). Resumed to ``steps``, such a
    run has nothing left to train.
    """
    final = _model_steps(out / "model.zip") if (out / "model.zip").is_file() else None
    found = checkpoints(out / "checkpoints")
    if final is None or final < steps or (found and found[-1][0] > final):
        return None
    try:
        ended = read_record(out / "config.json").get("env_steps")
    except (OSError, ValueError):
        return None
    return final if ended == final else None


def _no_run(out: Path, earlier: list[Path]) -> str:
    """Why ``out`` holds no run to resume (it has no ``config.json``), and what to do."""
    if earlier:  # checkpoints whose run is unknown may be another task's network
        return (
            f"--resume: {out} holds {earlier[0].name} but no config.json to check it against; "
            "start afresh (--force or another --out)"
        )
    found = foreign_names(out)
    if found:  # another command's output: a run started there would be mixed into it
        return (
            f"--resume: no run to resume in {out}: it holds {', '.join(found)}, not a training "
            "run (no config.json); train into another --out"
        )
    return f"--resume: no run to resume in {out} (start one without --resume)"


def prepare_output(out: Path, resume: bool, force: bool, config: TrainConfig | None = None) -> None:
    """Refuse to overwrite an earlier run's model unless asked to resume or to start afresh.

    With ``force`` the earlier run's ``model.zip``, checkpoints and logs are
    deleted (a later resume would otherwise continue from them). With
    ``resume`` the folder must hold a run's ``config.json`` (a run stopped
    before its first model holds it alone, and starts again), and with a
    ``config`` it must record the same run (:func:`check_resumed`).

    Raises:
        FileExistsError: If ``out`` holds a model or checkpoints and neither
            ``resume`` nor ``force`` is set, or, unless ``resume``, another
            command's files (:func:`foreign_names`; ``force`` deletes none of them).
        ResumeMismatch: With ``resume``, if ``out`` holds no run (nothing, or
            another command's files), a model without the ``config.json`` that
            would say which run it is, or another run than ``config``.
        ValueError: If both ``resume`` and ``force`` are set.
    """
    if resume and force:
        raise ValueError("resume and force: choose one (continue the run, or start afresh)")
    found = foreign_names(out)
    if found and not resume:  # a run there would be mixed into another command's output
        raise FileExistsError(
            f"{out} holds {', '.join(found)}: another command's files, not a training run's "
            "(--force deletes a run's alone); train into another --out"
        )
    earlier = earlier_models(out)
    if resume and not (out / "config.json").is_file():
        raise ResumeMismatch(_no_run(out, earlier))
    if resume and config is not None:
        check_resumed(out / "config.json", config)
    if not earlier or resume:
        return
    if not force:
        raise FileExistsError(
            f"{out} holds an earlier run's model ({earlier[0]}); resume it (--resume) or "
            "overwrite it (--force)"
        )
    for path in earlier:
        path.unlink()
    shutil.rmtree(out / "logs", ignore_errors=True)  # the earlier run's, resumed ones' too
