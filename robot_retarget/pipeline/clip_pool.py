"""Pools that convert many clips: in this process, or on Ray workers (the ``[scale]`` extra).

Both hold one :class:`ClipConverter` per worker, built once when the pool starts (the CasADi
solver is loaded from the disk cache or JIT-compiled once per worker, never per clip), and
yield a :class:`ClipReport` per clip as clips finish. Ray's start-up and the workers' solver
builds happen in ``__enter__`` (timed as ``startup_s``), outside the per-clip path.

On Ray each worker is an actor with one clip in flight at a time; clips go out longest file
first, so the last clips to finish are short ones. A worker that dies (killed, out of memory)
fails only the clip it held, which is reported like any other failure; a fresh worker takes its
place and the job goes on. ``ray.init(address=...)`` joins an existing cluster (its nodes need
robot-retarget installed and the input and output folders on a shared file system); without
an address a local Ray instance with ``num_cpus=workers`` is started and shut down again. On a
cluster without a worker count, one worker per CPU the cluster has.
"""

from __future__ import annotations

import os
import time
from collections.abc import Iterator, Sequence
from types import ModuleType, TracebackType
from typing import Any

from robot_retarget.errors import RetargetError
from robot_retarget.pipeline.clip_converter import (
    ClipConverter,
    ClipJob,
    ClipReport,
    ConvertOptions,
)

SCALE_INSTALL = 'python3 -m pip install "robot-retarget[scale]"  (or: pip install "ray>=2.9")'


class ScaleExtraMissingError(RetargetError):
    """``--workers`` > 1 or ``--ray-address`` needs Ray, which is not installed.
    ``workers``: the workers asked for (0: a cluster's, --ray-address); ``install_command``:
    what installs it."""

    def __init__(self, workers: int, reason: str) -> None:
        self.workers = workers
        self.install_command = SCALE_INSTALL
        self.reason = reason
        asked = f"--workers {workers}" if workers else "--ray-address"
        super().__init__(
            f"{asked} runs clips on Ray, which cannot be imported ({reason}); "
            f"install the [scale] extra: {SCALE_INSTALL}, or run with --workers 1"
        )


class RayClusterError(RetargetError):
    """Ray did not start, the cluster at ``address`` could not be joined, or the workers did
    not start on it (``workers_failed``); ``reason`` is Ray's own message."""

    def __init__(self, address: str | None, reason: str, *, workers_failed: bool = False) -> None:
        self.address = address
        self.reason = reason
        self.workers_failed = workers_failed
        if workers_failed:
            text = (
                f"the conversion workers did not start ({reason}); on a cluster every node needs "
                "robot-retarget installed (the same version) and the robot configs and model"
            )
        elif address is None:
            text = f"a local Ray instance did not start ({reason}); run with --workers 1"
        else:
            text = (
                f"cannot join the Ray cluster at {address} ({reason}); check `ray status` on its "
                "head node, pass --ray-address auto on a cluster node, or leave --ray-address out"
            )
        super().__init__(text)


def import_ray(workers: int) -> ModuleType:
    try:
        import ray
    except ImportError as exc:
        raise ScaleExtraMissingError(workers, str(exc)) from exc
    return ray


class LocalClipPool:
    """Clips one after another in this process (``--workers 1``)."""

    def __init__(self, options: ConvertOptions) -> None:
        self.options = options
        self.startup_s = 0.0
        self._converter: ClipConverter | None = None

    def __enter__(self) -> LocalClipPool:
        t0 = time.perf_counter()
        self._converter = ClipConverter(self.options)
        self.startup_s = time.perf_counter() - t0
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self._converter = None

    def convert(self, jobs: Sequence[ClipJob]) -> Iterator[ClipReport]:
        if self._converter is None:
            raise RuntimeError("use the pool in a with block")
        for job in jobs:
            yield self._converter.convert(job)


class _ClipWorker:
    """The Ray actor: one ClipConverter per worker process."""

    def __init__(self, options: ConvertOptions) -> None:
        self.converter = ClipConverter(options)

    def ready(self) -> bool:
        return True

    def pid(self) -> int:
        return os.getpid()

    def convert(self, job: ClipJob) -> ClipReport:
        return self.converter.convert(job)


class RayClipPool:
    """``workers`` Ray actors converting clips; see the module docstring."""

    def __init__(
        self, options: ConvertOptions, workers: int | None, address: str | None = None
    ) -> None:
        if workers is not None and workers < 1:
            raise ValueError(f"workers must be >= 1, got {workers}")
        if workers is None and address is None:
            raise ValueError("a local Ray instance needs a worker count")
        self.options = options
        self.workers = workers or 0  # 0 until an existing cluster says how many CPUs it has
        self.address = address
        self.startup_s = 0.0
        self.ray = import_ray(workers or 0)
        self._started_ray = False
        self._actor_class: Any = None
        self._actors: list[Any] = []

    def __enter__(self) -> RayClipPool:
        ray = self.ray
        t0 = time.perf_counter()
        if not ray.is_initialized():
            try:
                if self.address is None:
                    ray.init(
                        address="local",  # a new instance, whatever RAY_ADDRESS or `ray start` say
                        num_cpus=self.workers,
                        include_dashboard=False,
                        log_to_driver=False,
                        logging_level="warning",
                    )
                else:
                    ray.init(address=self.address, log_to_driver=False, logging_level="warning")
            except (ConnectionError, RuntimeError, ValueError) as exc:
                raise RayClusterError(self.address, _first_line(exc)) from exc
            self._started_ray = True
        if not self.workers:  # one worker per CPU of the cluster joined
            self.workers = max(1, int(ray.cluster_resources().get("CPU", 1)))
        self._actor_class = ray.remote(num_cpus=1)(_ClipWorker)
        self._actors = [self._new_actor() for _ in range(self.workers)]
        try:
            ray.get([a.ready.remote() for a in self._actors])  # every solver built before clip 1
        except ray.exceptions.RayError as exc:
            self.__exit__(None, None, None)  # no with-block exit follows a failed enter
            raise RayClusterError(self.address, _last_line(exc), workers_failed=True) from exc
        self.startup_s = time.perf_counter() - t0
        return self

    def _new_actor(self) -> Any:
        return self._actor_class.remote(self.options)

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        for actor in self._actors:
            self.ray.kill(actor)
        self._actors = []
        if self._started_ray:
            self.ray.shutdown()
            self._started_ray = False

    def actor_pids(self) -> list[int]:
        """The worker processes' ids (to watch or stop a worker from outside)."""
        return [int(p) for p in self.ray.get([a.pid.remote() for a in self._actors])]

    def convert(self, jobs: Sequence[ClipJob]) -> Iterator[ClipReport]:
        ray = self.ray
        queue = sorted(jobs, key=_file_size, reverse=True)  # longest first: short tails
        in_flight: dict[Any, tuple[int, ClipJob]] = {}
        idle = list(range(len(self._actors)))
        while queue or in_flight:
            while queue and idle:
                k = idle.pop()
                job = queue.pop(0)
                in_flight[self._actors[k].convert.remote(job)] = (k, job)
            ready, _ = ray.wait(list(in_flight), num_returns=1)
            ref = ready[0]
            k, job = in_flight.pop(ref)
            try:
                report: ClipReport = ray.get(ref)
            except ray.exceptions.RayActorError as exc:
                report = ClipReport(job.clip, job.out, error=f"the worker died: {_first_line(exc)}")
                self._actors[k] = self._new_actor()  # a fresh worker for the remaining clips
            except ray.exceptions.RayError as exc:
                report = ClipReport(job.clip, job.out, error=_first_line(exc))
            idle.append(k)
            yield report


def _file_size(job: ClipJob) -> int:
    try:
        return job.clip.stat().st_size
    except OSError:
        return 0


def _last_line(exc: BaseException) -> str:
    """The cause at the end of a remote traceback."""
    lines = [ln for ln in str(exc).splitlines() if ln.strip()]
    return lines[-1].strip() if lines else type(exc).__name__


def _first_line(exc: BaseException) -> str:
    lines = [ln for ln in str(exc).splitlines() if ln.strip()]
    return lines[0] if lines else type(exc).__name__
