"""``navgym render ID --seed S --out episode.mp4 [--policy plain|random] [--steps N]``: a video.

A plugin of the ``navgym`` command line (:mod:`navgym.cli`). Runs one episode of ``ID`` with
``render_mode="rgb_array"`` and writes it through Gymnasium's ``RecordVideo`` (moviepy, the
``render`` extra). Where moviepy or its ffmpeg is missing, or ``--out`` ends in ``.gif``, the
frames are written as a GIF with imageio instead (said on stderr). ``--policy plain`` holds the
task's neutral action (the plain filter), ``random`` samples the action space (seeded by
``--seed``). Imports no ``agents`` code.
"""

from __future__ import annotations

import argparse
import shutil
import sys
import tempfile
from pathlib import Path
from typing import Any


def _policy(env: Any, name: str, seed: int):
    if name == "random":
        env.action_space.seed(seed)
        return lambda: env.action_space.sample()
    import numpy as np

    neutral = np.asarray(env.unwrapped.core.task.neutral_action(), dtype=env.action_space.dtype)
    neutral = neutral.reshape(env.action_space.shape)
    return lambda: neutral


def _episode(env: Any, seed: int, policy: str, steps: int | None) -> int:
    env.reset(seed=seed)
    act = _policy(env, policy, seed)
    n = 0
    while steps is None or n < steps:
        _, _, terminated, truncated, _ = env.step(act())
        n += 1
        if terminated or truncated:
            break
    return n


def _have_moviepy() -> bool:
    try:
        import imageio_ffmpeg  # type: ignore[import-untyped]
        import moviepy  # type: ignore[import-untyped]  # noqa: F401

        imageio_ffmpeg.get_ffmpeg_exe()
    except Exception:
        return False
    return True


def write_video(
    env_id: str, out: str, seed: int = 0, policy: str = "plain", steps: int | None = None
) -> Path:
    """Run one episode and write its video to ``out``; returns the file written (``.gif`` fallback)."""
    import gymnasium as gym

    import navgym  # noqa: F401  (registers the ids)

    target = Path(out)
    target.parent.mkdir(parents=True, exist_ok=True)
    env = gym.make(env_id, render_mode="rgb_array")
    try:
        if target.suffix.lower() != ".gif" and _have_moviepy():
            from gymnasium.wrappers import RecordVideo

            with tempfile.TemporaryDirectory() as tmp:
                folder = Path(tmp) / "video"  # RecordVideo warns about an existing folder
                rec = RecordVideo(
                    env,
                    str(folder),
                    name_prefix="navgym",
                    episode_trigger=lambda _: True,
                    disable_logger=True,
                )
                _episode(rec, seed, policy, steps)
                rec.close()
                written = sorted(folder.glob("*.mp4"))
                if not written:
                    raise RuntimeError("RecordVideo wrote no video")
                shutil.move(str(written[0]), target)
            return target
        if target.suffix.lower() != ".gif":
            target = target.with_suffix(".gif")
            print(f"navgym render: moviepy/ffmpeg not available; writing a GIF: {target}", file=sys.stderr)
        import imageio.v2 as imageio

        frames: list[Any] = []
        env.reset(seed=seed)
        frames.append(env.render())
        act = _policy(env, policy, seed)
        n = 0
        while steps is None or n < steps:
            _, _, terminated, truncated, _ = env.step(act())
            frames.append(env.render())
            n += 1
            if terminated or truncated:
                break
        imageio.mimsave(target, frames, duration=1000 / env.metadata.get("render_fps", 10))
        return target
    finally:
        env.close()


def _run(args: argparse.Namespace) -> int:
    path = write_video(args.env_id, args.out, args.seed, args.policy, args.steps)
    print(f"wrote {path}")
    return 0


def register(subparsers: Any) -> None:
    """Add ``render`` to the ``navgym`` sub-commands (``subparsers`` of argparse)."""
    parser = subparsers.add_parser(
        "render",
        help="write a video of one episode (RecordVideo; GIF fallback)",
        description=__doc__.splitlines()[0],
    )
    parser.add_argument("env_id", metavar="ID", help="a navgym id, e.g. navgym/GpsInsFading-v2")
    parser.add_argument("--seed", type=int, default=0, help="reset seed (default 0)")
    parser.add_argument("--out", default="episode.mp4", help="output file (.mp4, or .gif)")
    parser.add_argument(
        "--policy", choices=("plain", "random"), default="plain", help="plain: neutral action"
    )
    parser.add_argument(
        "--steps", type=int, default=None, help="at most N steps (default: the whole episode)"
    )
    parser.set_defaults(_run=_run)
