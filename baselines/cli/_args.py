"""Argument types of the trackers' commands."""

from __future__ import annotations

import argparse
import contextlib
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

from baselines import MAX_PARTICLES
from humotion_gym.cli._common import (
    CommandError,
    Distinct,
    UsageError,
    int_at_least,
    refused_as,
    task_name,
)

#: ``--particles``: 1 to :data:`~baselines.MAX_PARTICLES`.
particle_count = int_at_least(1, MAX_PARTICLES)


def tracked_task(text: str) -> str:
    """An argparse ``type`` for a task the trackers track: :func:`task_name`, version 2 on.

    A ``-v1`` task is refused here, in one line and before any warning of
    Gymnasium's: its observation is the frame alone, which no agent reads.
    """
    from humotion_gym.envs.tasks import get_task

    name = task_name(text)
    spec = get_task(name)
    if spec.version < 2:
        raise argparse.ArgumentTypeError(
            f"{name} is deprecated and its observation is the frame alone, which the agents "
            f"do not track; use {spec.family}-v2 (docs/v1.md keeps version 1's numbers)"
        )
    return name


def agent_name(text: str) -> str:
    """An argparse ``type`` for a registered agent (``hold``, ``pf-tree``...)."""
    # learned: PATH.zip, LABEL=PATH.zip, pf-PRIOR+POLICY
    from baselines.agents import agent_names, is_learned
    from baselines.agents.learned import policy_file, policy_spec, takes_particles

    if text not in agent_names() and Path(text).is_dir():
        raise argparse.ArgumentTypeError(_folder_for_policy(text, Path(text)))
    with refused_as(argparse.ArgumentTypeError, ValueError):  # =PATH.zip: a row without name
        learned = is_learned(text)
    if text not in agent_names() and not learned:
        raise argparse.ArgumentTypeError(
            f"unknown agent {text[:80]}; the agents are {', '.join(agent_names())}, each "
            "described by humotion-gym agents (one of yours needs --import MODULE)"
        )
    if takes_particles(text):  # pf-PRIOR+POLICY
        prior, spec = text.split("+", 1)[0], policy_spec(text)
        if prior not in agent_names():
            raise argparse.ArgumentTypeError(
                f"{text[:80]}: unknown particle filter {prior[:40]} before the '+'; "
                "humotion-gym agents lists them"
            )
        if spec not in ("bc", "ppo") and not spec.endswith(".zip"):
            raise argparse.ArgumentTypeError(
                f"{text[:80]}: expected bc, ppo or a saved policy PATH.zip after the '+'"
            )
    path = policy_file(text)
    if path is not None and path.is_dir():
        raise argparse.ArgumentTypeError(_folder_for_policy(text, path))
    if path is not None and not path.is_file():
        raise argparse.ArgumentTypeError(f"{text[:80]}: no such policy file {str(path)[:80]}")
    return text


def _folder_for_policy(text: str, folder: Path) -> str:
    """Why a folder is not an agent: a saved policy is a file (a train run's model.zip)."""
    model = folder / "model.zip"
    hint = f" (the run's policy is {model})" if model.is_file() else ""
    return f"{text[:80]}: a folder; expected a saved policy file PATH.zip{hint}"


def add_particles(parser: argparse.ArgumentParser, what: str = "particles") -> None:
    """``--particles``: one particle count, default 300."""
    parser.add_argument(
        "--particles", type=particle_count, default=300,
        help=f"{what}, 1 to {MAX_PARTICLES:,} (default: 300)",
    )  # fmt: skip


def add_imports(parser: argparse.ArgumentParser) -> None:
    """``--import MODULE``, declared for ``--help`` and the parser.

    The import itself happens before the arguments are parsed
    (:func:`baselines.cli.import_agent_modules`), so that ``--agents`` knows its agents.
    """
    parser.add_argument(
        "--import", dest="imports", action="append", default=[], metavar="MODULE",
        help="import MODULE first: yours, registering agents with "
        "baselines.agents.register_agent or register_reference (from PYTHONPATH or the "
        "current folder; repeatable) (default: none)",
    )  # fmt: skip


def add_agents(parser: argparse.ArgumentParser, hold: str = "hold always runs") -> None:
    """``--agents``: registered agent names, default pf-cv pf-tree (``hold`` runs besides)."""
    parser.add_argument(
        "--agents", type=agent_name, nargs="+", action=Distinct, default=["pf-cv", "pf-tree"],
        metavar="AGENT",
        help=f"agents; {hold}; yours with --import (default: pf-cv pf-tree)",
    )  # fmt: skip
    add_imports(parser)


def add_engine(parser: argparse.ArgumentParser) -> None:
    """``--engine``, ``--workers``, ``--address``: where a leaderboard's episodes run."""
    parser.add_argument(
        "--engine", choices=["inprocess", "ray"], default="inprocess",
        help="where episodes run: in this process, or on Ray (the distributed extra) "
        "(default: inprocess)",
    )  # fmt: skip
    parser.add_argument(
        "--workers", type=int_at_least(1, 4096), default=None,
        help="with --engine ray: workers (one CPU each) of a local Ray started here, or "
        "actors on the cluster of --address (default: every CPU)",
    )  # fmt: skip
    parser.add_argument(
        "--address", default=None,
        help="with --engine ray: the Ray cluster to join (default: $RAY_ADDRESS if set, "
        "else a local Ray)",
    )  # fmt: skip


def check_engine(args: argparse.Namespace) -> None:
    """Refuse ``--workers``/``--address`` without ``--engine ray``, and an address of no form."""
    from baselines.leaderboard.ray_setup import check_ray_address_form

    given = [flag for flag in ("workers", "address") if getattr(args, flag) is not None]
    if args.engine != "ray" and given:
        raise UsageError(f"{', '.join('--' + f for f in given)}: only with --engine ray")
    if args.address is not None:
        with refused_as(UsageError, ValueError, "--"):
            check_ray_address_form(args.address)


@contextlib.contextmanager
def engine_errors() -> Iterator[None]:
    """Ray's failures, in one line naming the flag: ``leaderboard``'s and ``sweep``'s."""
    from baselines.leaderboard.engine import BadWorkers, WorkerStartError
    from baselines.leaderboard.ray_setup import NoRayCluster

    try:
        yield
    except ModuleNotFoundError as exc:
        if exc.name != "ray":
            raise
        raise CommandError(f"--engine ray: {exc}") from None
    except NoRayCluster as exc:  # --address where no Ray cluster listens
        raise CommandError(f"--{exc}") from None
    except ConnectionError as exc:  # Ray's own: no cluster for auto, a refused token
        raise CommandError(f"--address: {exc}") from None
    except BadWorkers as exc:  # more workers than the joined cluster's CPUs
        raise UsageError(f"--workers: {exc}") from None
    except WorkerStartError as exc:  # a worker of another version, or that cannot take an agent
        raise CommandError(f"--engine ray: {exc}") from None


def key_value(text: str) -> tuple[str, float]:
    """An argparse ``type``: ``KEY=VALUE`` with a numeric value (an int where written as one)."""
    key, sep, value = text.partition("=")
    if not sep or not key:
        raise argparse.ArgumentTypeError(f"expected KEY=VALUE, got {text!r}")
    try:
        number = float(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{key}: expected a number, got {value!r}") from None
    return key, int(number) if number.is_integer() and "." not in value else number


class Settings(argparse.Action):
    """``KEY=VALUE`` pairs gathered over every use of the flag; a key given twice is refused.

    ``--set a=1 --set b=2`` sets both (argparse's own list flags keep only the
    last use, which would drop ``a`` without a word).
    """

    def __call__(
        self,
        parser: argparse.ArgumentParser,
        namespace: argparse.Namespace,
        values: Any,
        option_string: str | None = None,
    ) -> None:
        pairs = [*(getattr(namespace, self.dest, None) or []), *values]
        keys = [key for key, _ in pairs]
        twice = sorted({key for key in keys if keys.count(key) > 1})
        if twice:
            parser.error(f"{option_string}: {', '.join(twice)} given twice")
        setattr(namespace, self.dest, pairs)


def key_setting(text: str) -> tuple[str, float | str]:
    """An argparse ``type``: ``KEY=VALUE``, a number where the value reads as one, else a word."""
    key, _, value = text.partition("=")
    try:
        return key_value(text)
    except argparse.ArgumentTypeError:
        if not key or not value.replace("_", "").isalnum():
            raise argparse.ArgumentTypeError(
                f"expected KEY=VALUE (a number or a word), got {text[:80]!r}"
            ) from None
    return key, value


def check_policy_files(agents: Sequence[str]) -> None:
    """Refuse a saved policy in ``--agents`` that is no policy, before any episode runs.

    Raises:
        CommandError: Naming ``--agents`` and the file (what loading it said).
    """
    from baselines.agents.learned import load_policy, policy_file

    for name in agents:
        path = policy_file(name)
        if path is not None:
            with refused_as(CommandError, ValueError, "--agents: "):
                load_policy(path)
