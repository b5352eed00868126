"""``humotion-gym track``: track seeded episodes with an agent; errors and timing.

::

    humotion-gym track --task ArmTrack-v2 --agent pf-tree --particles 300 --episodes 20
"""

from __future__ import annotations

import argparse
import warnings
from pathlib import Path
from typing import Any

import numpy as np

from baselines.cli._args import add_imports, add_particles, agent_name, tracked_task
from humotion_gym.cli._common import (
    CommandError,
    UsageError,
    add_command,
    add_data_dir,
    add_int,
    add_json,
    add_seed,
    add_task,
    check_memory,
    check_mocap_paths,
    env_kwargs,
    episode_count,
    json_text,
    output_file,
    wrote,
)

#: Printed under the table: what its columns and summary mean.
LEGEND = (
    "mean/final mm: keypoint error averaged over the episode's frames / at its last frame; "
    "lost at: where the first run of frames above the task's lost-track threshold that is "
    "long enough to count as lost began (- if never; 0 is the first scored frame); "
    "IQM: interquartile mean over the "
    "episodes (the mean of the middle 50%); CI: 95% bootstrap interval."
)


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add ``track``."""
    track = add_command(
        subparsers, "track", "track seeded episodes with an agent; errors and timing",
        "humotion-gym track --task ArmTrack-v2 --agent pf-tree --particles 300 --episodes 20",
    )  # fmt: skip
    add_task(track, "ArmTrack-v2", "task id, see humotion-gym tasks", kind=tracked_task)
    track.add_argument(
        "--agent", type=agent_name, default="pf-cv",
        help="agent, see humotion-gym agents; yours with --import (default: pf-cv)",
    )  # fmt: skip
    add_imports(track)
    add_particles(track, "particles of a particle-filter agent")
    add_int(track, "--episodes", 20, "episodes to track", episode_count)
    add_seed(track, "seed of the first episode and of the agent")
    track.add_argument(
        "--clip", default=None,
        help="a clip id of the library (synthetic/walk-01, cmu/02_01; see humotion-gym data "
        "table) or a BVH/AMC file, which needs --data-dir for the priors' training clips "
        "(default: the task's draw)",
    )  # fmt: skip
    track.add_argument(
        "--video", type=output_file(".mp4", ".avi"), default=None,
        help="also write a video of the first episode here (default: none)",
    )  # fmt: skip
    add_json(track, "print one JSON object with every episode instead of a table")
    add_data_dir(track)
    track.set_defaults(func=_cmd_track)


def _clip_options(args: argparse.Namespace) -> dict[str, str] | None:
    """The reset options of ``--clip``: a clip id, or a mocap file (checked here).

    A file needs real mocap (``--data-dir``) for the priors' training persons,
    unless the agent fits nothing (a reference).

    Raises:
        FileNotFoundError: If ``--clip`` names a missing ``.bvh``/``.amc`` file.
        UsageError: If a file is given without a folder of real mocap.
    """
    from humotion_gym.mocap.library import MOCAP_ENV, configured_data_dirs

    if not args.clip:
        return None
    path = Path(args.clip)
    if path.suffix.lower() not in (".bvh", ".amc") and not path.is_file():
        return {"clip_id": args.clip}
    if not path.is_file():
        raise FileNotFoundError(f"--clip: {args.clip}: no such file")
    check_mocap_paths([path], "--clip")
    from baselines.agents import REFERENCES

    if not configured_data_dirs(args.data_dir) and args.agent not in REFERENCES:
        raise UsageError(
            f"--clip {args.clip}: give --data-dir DIR (or set ${MOCAP_ENV}) with real mocap; "
            "the priors are fitted on its training persons, else on synthetic motion"
        )
    return {"file": str(path)}


def _warn_if_trained_on(clip: str, options: dict[str, str], library: Any) -> None:
    """Warn where ``--clip`` shows a training person: by its name, or a file by its skeleton."""
    from humotion_gym.mocap.library import load_library
    from humotion_gym.mocap.persons import skeleton_owner

    if "clip_id" in options:
        motion = library[options["clip_id"]]
        person = None if motion.subject in library.held_out else motion.subject
    else:
        motion = load_library([options["file"]], fps=library[0].fps, progress=False)[0]
        train = library.split("train")
        owner = skeleton_owner(motion, train)
        person = next((m.meta.get("person", owner) for m in train if m.subject == owner), None)
    if person is not None:
        warnings.warn(
            f"--clip {clip} shows a training person ({person}): the priors and policies "
            "learned from this person, so its errors are not held-out numbers",
            stacklevel=1,
        )


def _cmd_track(args: argparse.Namespace) -> int:
    import gymnasium as gym

    from baselines.agents import REFERENCES, make, uses_particles
    from baselines.agents.base import TaskNotSupported
    from baselines.leaderboard.evaluation import evaluate, run_episode, summarize, warm_up
    from humotion_gym.video import write_video

    options = _clip_options(args)
    render_mode = "rgb_array" if args.video else None
    env = gym.make(
        f"humotion_gym/{args.task}", terminate_on_lost=False, render_mode=render_mode,
        **{"split": "test", **env_kwargs(args)},
    )  # fmt: skip
    if options and "clip_id" in options:
        library = env.unwrapped.library  # type: ignore[attr-defined]
        if options["clip_id"] not in library.clip_ids:
            near = [c for c in library.clip_ids if c.endswith("/" + options["clip_id"])]
            hint = f"; did you mean {near[0]}?" if near else " (see humotion-gym data table)"
            synthetic = all(c.startswith("synthetic/") for c in library.clip_ids)
            if not near and synthetic and not args.clip.startswith("synthetic/"):
                hint = " (the built-in synthetic library; real mocap needs --data-dir)"
            raise UsageError(f"--clip: no clip {args.clip} in the task's library{hint}")
        label, wanted = library[options["clip_id"]].label, env.unwrapped.task.labels  # type: ignore[attr-defined]
        if wanted is not None and label not in wanted:  # tracked, but not the task's motion
            warnings.warn(
                f"--clip {args.clip} is a {label} clip; {args.task} draws only {', '.join(wanted)}",
                stacklevel=1,
            )
    if options and args.agent not in REFERENCES:
        _warn_if_trained_on(args.clip, options, env.unwrapped.library)  # type: ignore[attr-defined]
    if args.video:
        shape = env.observation_space["frame"].shape  # type: ignore[index]
        # render() is every view side by side, in RGB: (H, views * W, 3)
        size = int(np.prod(shape[-3:-1])) * (shape[0] if len(shape) == 4 else 1) * 3
        frames_per_episode = env.unwrapped.episode_frames  # type: ignore[attr-defined]
        check_memory("--video", frames_per_episode, size, "frames of the first episode")
    try:
        agent = make(args.agent, env, n_particles=args.particles, seed=args.seed)
    except TaskNotSupported as exc:  # --agent and --task conflict, as the leaderboard skips
        raise UsageError(f"--agent: {exc}") from None
    except ValueError as exc:  # a policy file that is not one
        raise CommandError(f"--agent: {exc}") from None
    warm_up_s = warm_up(agent, env, args.seed, options)
    results = evaluate(agent, env, args.episodes, seed=args.seed, options=options, progress=True)
    if args.video:
        frames: list = []
        run_episode(agent, env, args.seed, options, on_frame=lambda f, i: frames.append(f))
        write_video(args.video, frames, fps=env.unwrapped.metadata["render_fps"])
    summary = summarize(results)
    if args.json:
        print(json_text({
            "task": args.task, "agent": args.agent,
            "particles": args.particles if uses_particles(args.agent) else None,
            # what reruns it: the first episode's seed (the agent's too), clip, data
            "seed": args.seed, "clip": args.clip, "data_dir": args.data_dir or None,
            "episodes": [r.to_dict() for r in results], "summary": summary,
            "video": str(args.video) if args.video else None, "warm_up_s": warm_up_s,
        }))  # fmt: skip
        return 0
    # references and learned policies take no particles
    n = getattr(agent, "n_particles", args.particles)
    print(f"{args.task}  {args.agent}  {f'{n} particles' if n else 'no particles'}")
    width = max([4] + [len(r.clip_id) for r in results])
    print(
        f"{'seed':>5s} {'clip':{width}s} {'mean mm':>8s} {'final mm':>9s} "
        f"{'lost at':>8s} {'ms/frame':>9s}"
    )
    for r in results:
        lost = "-" if r.lost_frame is None else str(r.lost_frame)
        print(f"{r.seed:5d} {r.clip_id:{width}s} {r.mean_error_mm:8.1f} {r.final_error_mm:9.1f} "
              f"{lost:>8s} {r.ms_per_frame:9.2f}")  # fmt: skip
    lo, hi = summary["mean_error_ci"]
    llo, lhi = summary["lost_fraction_ci"]
    print(
        f"mean error {summary['mean_error_mm']:.1f} mm (95% CI {lo:.1f}-{hi:.1f}), "
        f"IQM {summary['iqm_error_mm']:.1f} mm, lost {summary['lost_fraction']:.0%} "
        f"(95% CI {llo:.0%}-{lhi:.0%}), {summary['ms_per_frame']:.2f} ms/frame"
    )
    print(LEGEND)
    print(
        f"first calls {warm_up_s:.2f} s, before the episodes and not in ms/frame: on a "
        "first run numba compiles its kernels there, then loads them from its cache"
    )
    if args.video:
        wrote(args.video, f"the first episode, seed {args.seed}")
    return 0
