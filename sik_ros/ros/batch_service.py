"""``~/solve_ik_batch``: many IK targets in one request, each answered as ``~/solve_ik`` would.

:func:`solve_batch_request` first checks what the whole request asks: at most
``max_batch_targets`` targets and at least one, then the solution count, the seed (its names and
its values), the obstacles and the timeout (:func:`~sik_ros.ros.ik_service.solve_options`, the
checks of ``~/solve_ik``). A problem there raises its :class:`~sik_ros.errors.SikError`, which
:class:`~sik_ros.ros.guard.RequestGuard` makes the response's code, and nothing is solved. Then
each target is checked and solved in turn with :func:`~sik_ros.ros.ik_service.checked_goal` and
:func:`~sik_ros.ros.ik_service.solve_goal`, the code of ``~/solve_ik``: a bad target (another
frame, NaN, a zero quaternion) gets its own code and message in its ``SolveIKResult``, and the
others are answered.

With solver processes (``solver_processes`` > 0) the targets are answered by :func:`lanes`
threads at once, each taking the next target in turn (:class:`_BatchRun`), so every process
solves while the node turns answers into messages; without them, one target after another
(clones in threads would only share the GIL). The results stay in target order.

Before each target a lane gives way (:class:`GiveWay`): while another request of the node is
being answered (``~/solve_ik``, ``~/goal``, ``/compute_ik``, ``~/solve_path``), it waits, for
one target's timeout at most, so that a request arriving during a batch shares the GIL (or the
solver processes) with the batch's targets in progress only. A refusal that comes up during a
batch (the node shutting down, a managed node deactivated, the arm no longer served) answers
the targets not yet taken with its code.
"""

from contextlib import contextmanager
from dataclasses import replace
import threading
import time
from typing import Callable, Iterator, List, Optional, Tuple

import numpy as np
from std_msgs.msg import Header

from sik_interfaces.msg import SolveIKResult
from sik_interfaces.srv import SolveIKBatch
from sik_ros.errors import InvalidGoal, SikError
from sik_ros.ros import conversions as conv
from sik_ros.ros.ik_service import Arm, checked_goal, fill_answer, solve_goal, solve_options
from sik_ros.ros.params import NodeParams
from sik_ros.serving.solvers import Solver

R = SolveIKBatch.Response
#: A refusal check (:meth:`~sik_ros.ros.guard.RequestGuard.refusal`): ``(code, message)`` or None.
Refusal = Callable[[], Optional[Tuple[int, str]]]


class GiveWay:
    """Batches wait between their targets while the node answers other requests.

    The node's :class:`~sik_ros.ros.guard.RequestGuard` counts the requests in flight and calls
    :meth:`answered` after each answer, which wakes the batches waiting. Safe from every
    executor thread.
    """

    def __init__(self, in_flight: Callable[[], int]):
        """Count the node's requests in flight with ``in_flight()`` (the guard's count)."""
        self._in_flight = in_flight
        self._batches = 0
        self._changed = threading.Condition()

    @contextmanager
    def batch(self) -> Iterator['GiveWay']:
        """Count a batch as one of the requests that give way while the block runs."""
        with self._changed:
            self._batches += 1
        try:
            yield self
        finally:
            with self._changed:
                self._batches -= 1
                self._changed.notify_all()

    def answered(self, where: str, code: int, seconds: float) -> None:
        """Wake the batches waiting, after an answer: a listener of the guard."""
        with self._changed:
            self._changed.notify_all()

    def others(self) -> int:
        """Requests in flight that are not batches."""
        return self._in_flight() - self._batches

    def wait(self, limit: float) -> float:
        """Wait while other requests are in flight, for ``limit`` seconds at most; the wait [s].

        0 when no other request is in flight.
        """
        with self._changed:
            if self.others() <= 0:
                return 0.0
            start = time.monotonic()
            deadline = start + limit
            while self.others() > 0:
                left = deadline - time.monotonic()
                if left <= 0:
                    break
                self._changed.wait(left)
            return time.monotonic() - start


def result_msg(code: int, message: str) -> SolveIKResult:
    """A target's answer without solutions (a bad target, a refusal)."""
    return SolveIKResult(error_code=int(code), message=message)


def solve_batch_request(solvers: Solver, arm: Arm, request: SolveIKBatch.Request, p: NodeParams,
                        state_seed: Callable[[], Optional[np.ndarray]],
                        check_seed: Callable[[np.ndarray], np.ndarray], header: Header,
                        give_way: GiveWay, refusal: Refusal
                        ) -> Tuple[int, str, List[SolveIKResult]]:
    """The code, message and per-target results of a ``SolveIKBatch`` request.

    Args:
        solvers: where to solve.
        arm: the served arm.
        request: the request (any field may be hostile).
        p: the parameters in force.
        state_seed: the latest ``joint_states`` as a seed (or None), used when the request
            gives none and ``use_joint_states`` is on.
        check_seed: the solver's check of a seed's values
            (:meth:`~sik_ros.solver.SelectiveIK.check_seed`): a seed outside the limits is the
            whole request's ``INVALID_SEED``, not every target's.
        header: the solutions' joint states' header.
        give_way: where the batch waits for the node's other requests between its targets.
        refusal: the node's refusal now, or None (checked between targets).

    Returns:
        ``SUCCESS`` (the request was valid), a summary of the targets' codes, and one
        ``SolveIKResult`` per target in order.

    Raises:
        SikError: a problem of the whole request (too many targets or none, the solution
            count, the seed, the obstacles, the timeout): the response's code.
    """
    start = time.perf_counter()
    count = len(request.targets)
    if count > p.max_batch_targets:
        raise InvalidGoal(f'{count} targets; at most {p.max_batch_targets} are accepted '
                          f'(parameter max_batch_targets)')
    if count == 0:
        raise InvalidGoal('no targets: give at least one')
    options = solve_options(arm, request, p, state_seed)
    if options.seed is not None:
        options = replace(options, seed=check_seed(options.seed))
    run = _BatchRun(request, count, refusal, give_way, options.timeout,
                    lambda i, target: _answer(solvers, arm, p, options, header, i, target,
                                              request.use_orientation))
    with give_way.batch():
        run.solve(min(lanes(solvers.processes()), count))
    return R.SUCCESS, summary(run.results, time.perf_counter() - start, run.waited), run.results


def _answer(solvers: Solver, arm: Arm, p: NodeParams, options, header: Header, i: int, target,
            use_orientation: bool) -> SolveIKResult:
    """Target ``i``'s ``SolveIKResult``: its solutions, or its own code for a bad target."""
    try:
        position, orientation = checked_goal(arm, target, use_orientation, 'target')
        answer = solve_goal(solvers, position, orientation, options, p)
    except SikError as exc:
        return result_msg(conv.error_code_for(exc), f'target {i}: {exc}')
    msg = result_msg(answer.code, answer.message)
    fill_answer(msg, answer, arm, header)
    return msg


class _BatchRun:
    """A batch's targets answered by one or more lanes (threads), each taking the next target.

    With solver processes the lanes' solves run at once (one lane per process); each lane
    checks the refusal and gives way before each of its targets. The results stay in target
    order.
    """

    def __init__(self, request, count: int, refusal: Refusal, give_way: GiveWay,
                 limit: float, answer: Callable[[int, object], SolveIKResult]):
        self._targets = request.targets
        self._refusal, self._give_way, self._limit, self._answer = refusal, give_way, limit, answer
        self._slots: List[Optional[SolveIKResult]] = [None] * count
        self._turns = iter(range(count))
        self._lock = threading.Lock()
        self._failed: List[Exception] = []
        #: time given way to other requests, summed over the lanes [s]
        self.waited = 0.0

    @property
    def results(self) -> List[SolveIKResult]:
        """One result per target, in order (after :meth:`solve`)."""
        return [r for r in self._slots if r is not None]

    def solve(self, lanes: int) -> None:
        """Answer every target on ``lanes`` lanes: this thread and ``lanes - 1`` more.

        Raises:
            Exception: what a lane met outside the targets' own errors (the guard answers it).
        """
        helpers = [threading.Thread(target=self._lane, name=f'sik_batch_{k}', daemon=True)
                   for k in range(lanes - 1)]
        for t in helpers:
            t.start()
        self._lane()
        for t in helpers:
            t.join()
        if self._failed:
            raise self._failed[0]

    def _lane(self) -> None:
        try:
            while not self._failed:
                with self._lock:
                    i = next(self._turns, None)
                if i is None:
                    return
                refused = self._refusal()
                if refused is not None:
                    self._slots[i] = result_msg(*refused)
                    continue
                waited = self._give_way.wait(self._limit)
                self._slots[i] = self._answer(i, self._targets[i])
                with self._lock:
                    self.waited += waited
        except Exception as exc:  # re-raised by solve() in the request's thread
            self._failed.append(exc)


def summary(results: List[SolveIKResult], seconds: float, waited: float) -> str:
    """The response's message: how many targets got each code, the time and the time given way."""
    counts: dict = {}
    for r in results:
        name = conv.ERROR_NAMES.get(r.error_code, str(r.error_code))
        counts[name] = counts.get(name, 0) + 1
    codes = ', '.join(f'{n} {name}' for name, n in sorted(counts.items(), key=lambda c: -c[1]))
    return (f'{len(results)} targets: {codes}; {seconds * 1e3:.1f} ms, of which '
            f'{waited * 1e3:.1f} ms given way to other requests')


def lanes(processes: int) -> int:
    """The lanes of a batch on ``processes`` solver processes: one more than them, or 1.

    While a lane turns an answer into messages (in this process, under the GIL), the other
    lanes keep every process solving; without processes, one lane (clones in threads would only
    share the GIL: two solve barely faster than one).
    """
    return processes + 1 if processes > 0 else 1
