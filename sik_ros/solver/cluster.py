"""Many targets on a Ray cluster: :meth:`SelectiveIK.solve_batch`'s chunks on solver actors.

:class:`RayExecutor` connects to a running Ray cluster (``address='auto'``, ``'host:6379'``,
``'ray://host:10001'``) or starts one on this machine (``address=None``). It places one actor
per worker, each loading the bundle once (a bundled name, or a folder at the same path on
every node of the cluster), and ``solve_batch(..., executor=...)`` sends it the chunks of
consecutive targets that local worker processes would get; the answers come back packed into
a few arrays per chunk (:func:`~sik_ros.solver.parallel.pack`), in target order. Ray is an
optional extra (``pip install sik_ros[ray]``): this module imports it when an executor is made.
"""

from typing import Any, Dict, Iterator, List, Optional, Tuple

from sik_ros.errors import InvalidArgument, SikError
from sik_ros.solver.parallel import check_workers

__all__ = ['RayExecutor']

#: Chunks per actor and batch: fewer and larger than local processes take (a task costs a few
#: milliseconds of scheduling and transfer), still enough to even out slow targets.
CHUNKS_PER_WORKER = 4
#: The local cluster's object store [bytes]: chunks of answers are small (about 20 kB per 100
#: pose goals of 16 solutions), and a machine's /dev/shm may be a few tens of MB.
LOCAL_OBJECT_STORE = 100_000_000


class ChunkSolver:
    """A Ray actor's body: one solver, loaded once, answering chunks of targets."""

    def __init__(self, bundle: str, config: Dict[str, Any], solver_class) -> None:
        """Load ``bundle`` with ``config`` (one thread for BLAS and torch)."""
        from sik_ros.solver import parallel
        parallel.single_threaded()
        from sik_ros.solver.config import SolverConfig
        self._solver = solver_class.load(bundle, SolverConfig(**config))

    def solve(self, start: int, pos, quat, seeds, kwargs) -> Tuple[int, Tuple[str, Any]]:
        """The chunk starting at target ``start``: its packed answers, or the error.

        The arrays arrive read-only from Ray's object store; the kernels take writable ones.
        """
        import numpy as np
        from sik_ros.solver import parallel
        pos, quat, seeds = (None if a is None else np.array(a) for a in (pos, quat, seeds))
        return start, parallel.solve_chunk_with(self._solver, pos, quat, seeds, kwargs)


class RayExecutor:
    """Solver actors on a Ray cluster, for :meth:`SelectiveIK.solve_batch` (``executor=``).

    Use it as a context manager, or call :meth:`close`: the actors are stopped, and the Ray
    session it opened is ended (a local cluster it started stops with it). Within a Ray
    session opened by the caller, it adds its actors to that session and leaves it open.
    """

    def __init__(self, address: Optional[str] = None, workers: Optional[int] = None):
        """Connect to the cluster at ``address``, or start one here (None).

        Args:
            address: ``ray.init``'s address: ``'auto'`` (a cluster running on this machine's
                network), ``'host:6379'``, ``'ray://host:10001'``; None starts a local cluster
                of ``workers`` CPUs.
            workers: actors (one CPU each); default, and at most: the cluster's free CPUs.

        Raises:
            SikError: Ray is not installed, the cluster cannot be reached, or it has no free
                CPU.
        """
        try:
            import ray
        except ImportError:
            raise SikError('a Ray executor needs Ray: pip install "sik_ros[ray]"') from None
        if workers is not None:
            workers = check_workers(workers)
        self._ray = ray
        self._actors: List[Any] = []
        self._loaded: Optional[Tuple[str, Any]] = None
        #: whether this executor opened the Ray session (and closes it)
        self._own = not ray.is_initialized()
        options = dict(include_dashboard=False, log_to_driver=False, configure_logging=False)
        if address is None:
            options.update(num_cpus=workers, object_store_memory=LOCAL_OBJECT_STORE)
        else:
            options.update(address=address)
        if self._own:
            try:
                ray.init(**options)
            except Exception as exc:  # Ray raises ConnectionError, RuntimeError, ValueError
                where = 'a local Ray cluster' if address is None else \
                    f'the Ray cluster at {address!r}'
                raise SikError(f'cannot start or reach {where}: {exc}') from None
        free = int(ray.available_resources().get('CPU', 0))
        if free < 1:
            self.close()
            raise SikError('the Ray cluster has no free CPU: other actors or tasks (another '
                           'RayExecutor?) hold every one')
        #: how many actors solve at once (one free CPU each)
        self.workers = min(workers or free, free)
        #: chunks of a batch per actor
        self.chunks_per_worker = CHUNKS_PER_WORKER

    def __enter__(self) -> 'RayExecutor':
        """The executor, closed when the block ends."""
        return self

    def __exit__(self, *exc) -> None:
        """Stop the actors (and the cluster this executor started)."""
        self.close()

    def solve_chunks(self, ik, chunks: List[Tuple[int, Any, Any, Any]],
                     kwargs: Dict[str, Any]) -> Iterator[Tuple[int, Tuple[str, Any]]]:
        """Each chunk ``(start, pos, quat, seeds)``'s reply, in the order they finish.

        Raises:
            InvalidArgument: ``ik`` has no bundle the actors could load.
        """
        if ik.bundle is None:
            raise InvalidArgument('a Ray executor needs a solver loaded from a bundle (the '
                                  'actors load it on their nodes)')
        from dataclasses import asdict
        key = (str(ik.bundle), asdict(ik.config))
        if self._loaded != key:
            self._stop_actors()
            actor = self._ray.remote(num_cpus=1)(ChunkSolver)
            self._actors = [actor.remote(key[0], key[1], type(ik)) for _ in range(self.workers)]
            self._loaded = key
        from ray.util import ActorPool
        pool = ActorPool(self._actors)
        yield from pool.map_unordered(
            lambda a, chunk: a.solve.remote(*chunk, kwargs), chunks)

    def close(self) -> None:
        """Stop the actors, and end the Ray session this executor opened (idempotent).

        A local cluster it started stops with it; a remote cluster keeps running.
        """
        self._stop_actors()
        if self._own and self._ray.is_initialized():
            self._ray.shutdown()

    def _stop_actors(self) -> None:
        for actor in self._actors:
            self._ray.kill(actor)
        self._actors, self._loaded = [], None
