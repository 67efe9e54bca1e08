"""The arm of robot_description, followed: served at once, learned in the background, cached.

Used by sik_node when neither ``robot`` nor ``model_dir`` names a bundle. A description (the
parameter at start-up, then every message on the ``robot_description`` topic) is checked and
keyed (:func:`~sik_ros.serving.arm_source.prepare_arm`); a chain the node already serves
changes nothing; another chain is served instead of the one before: requests are refused
(``NO_ROBOT``, saying so) for the seconds its solver takes to start, then answered from its
cached learned bundle or its table of configurations. With ``learning`` on, the arm's model
is built in the background (:class:`~sik_ros.serving.learner.BackgroundLearner`) and swapped
in when ready. A description that cannot be served leaves the node up, refusing requests with
the reason, and writes nothing to the cache.
"""

import threading
from typing import Callable, List, Optional, Protocol, Tuple

from sik_ros.errors import SikError
from sik_ros.serving.arm_source import (Arm, compare, first_solver, keep_verdict,
                                        load_learned, prepare_arm)
from sik_ros.serving.learner import BackgroundLearner
from sik_ros.solver import SelectiveIK, SolverConfig


class Host(Protocol):
    """What the follower needs of the node: its settings, a log, serving and refusing."""

    def solver_config(self) -> SolverConfig:
        """The solver settings of the node's parameters."""

    def install(self, ik: SelectiveIK, processes: int) -> None:
        """Serve ``ik`` (started with ``processes`` solver processes) from now on."""

    def refuse(self, reason: Optional[str]) -> None:
        """Refuse every request with ``reason`` (None: serve again)."""


class ArmFollower:
    """Follows robot_description for a node (see the module)."""

    def __init__(self, host: Host, params, info: Callable[[str], None],
                 error: Callable[[str], None]):
        self.host, self.params, self.info, self.error = host, params, info, error
        self.arm: Optional[Arm] = None
        self.learner: Optional[BackgroundLearner] = None
        self.learned = False
        #: the table of configurations being served (the learned model is held to it)
        self.table: Optional[SelectiveIK] = None
        #: what became of the learned model, for /diagnostics
        self.verdict = ''
        #: why no arm is served (a bad description, or none yet), for /diagnostics
        self.problem: Optional[str] = 'waiting for robot_description'
        self._lock = threading.Lock()

    def take(self, text: str, source: str) -> None:
        """Serve the chain of a description (from ``source``: parameter or topic)."""
        with self._lock:
            p = self.params
            try:
                arm = prepare_arm(text, p.base_frame, p.tip_frame, p.cache_dir or None)
            except SikError as exc:
                self._bad(f'robot_description ({source}) cannot be served: {exc}')
                return
            if self.arm is not None and arm.key == self.arm.key and self.problem is None:
                self.info(f'robot_description ({source}): the same chain; nothing changes')
                return
            self._switch(arm, source)

    def _bad(self, reason: str) -> None:
        self.error(reason)
        self._stop_learning()
        self.arm, self.learned, self.problem = None, False, reason
        self.host.refuse(reason)

    def _switch(self, arm: Arm, source: str) -> None:
        p = self.params
        if self.arm is not None:
            self.host.refuse(f'switching to the chain of a new robot_description ({source})')
        self._stop_learning()
        for note in arm.notes:
            self.info(note)
        if arm.missing_meshes:
            self.info(f'collision geometry: {len(arm.missing_meshes)} mesh(es) not found here '
                      f'(e.g. {arm.missing_meshes[0]}); those parts are left out of collision '
                      f'checks (put their package on ROS_PACKAGE_PATH to include them)')
        try:
            ik, learned = first_solver(arm, self.host.solver_config(), p.sweep_time, self.info)
            self.host.install(ik, p.solver_processes if learned else 0)
        except SikError as exc:
            self._bad(f'robot_description ({source}): its solver cannot start: {exc}')
            return
        self.arm, self.learned, self.problem = arm, learned, None
        self.table, self.verdict = (None if learned else ik), ''
        self.info(f'serving {arm.robot.name} {arm.robot.base_frame} -> {arm.robot.tip_frame} '
                  f'({arm.robot.dof} joints; cache key {arm.key}) from '
                  + ('its learned bundle' if learned else 'its table of configurations'))
        if not learned and p.learning:
            self.learner = BackgroundLearner(arm.entry, p.base_frame, p.tip_frame,
                                             p.learning_time, p.learning_rows, self.info)

    def poll(self) -> None:
        """Advance the background build; swap the learned model in when it is ready."""
        with self._lock:
            learner, arm = self.learner, self.arm
            if learner is None or arm is None:
                return
            bundle = learner.poll()
            if bundle is None:
                return
            ik = load_learned(arm, self.host.solver_config())
            if ik is None:
                self.error(f'the learned bundle {bundle} did not load: '
                           f'{"; ".join(arm.notes[-1:])}; serving the table of configurations')
                return
            if self.table is not None:
                figures = compare(self.table, ik)
                text = ', '.join(f'{g}: success {100 * f["success"]:.0f} % / '
                                 f'{100 * figures["table"][g]["success"]:.0f} %, distinct '
                                 f'{f["distinct_median"]:.0f} / '
                                 f'{figures["table"][g]["distinct_median"]:.0f}'
                                 for g, f in figures['learned'].items())
                if not keep_verdict(arm, figures):
                    self.verdict = f'kept the table: the learned model answered worse ({text})'
                    self.info(f'{self.verdict}; a longer learning_time trains a better one')
                    return
                self.verdict = f'learned / table: {text}'
            try:
                self.host.install(ik, self.params.solver_processes)
            except SikError as exc:
                self.error(f'the learned bundle {bundle} did not start: {exc}')
                return
            self.learned, self.table = True, None
            self.info(f'learned model swapped in: {bundle}'
                      + (f' ({self.verdict})' if self.verdict else ''))

    def values(self) -> List[Tuple[str, str]]:
        """What ``/diagnostics`` shows of the arm and its learning."""
        out = [('arm', 'none' if self.arm is None else
                f'{self.arm.robot.name} {self.arm.robot.base_frame} -> '
                f'{self.arm.robot.tip_frame}, cache key {self.arm.key}'),
               ('model', 'learned' if self.learned else 'table of configurations'
                if self.arm is not None else 'none')]
        if self.learner is not None and not self.learned:
            out += [(k.replace('_', ' '), v) for k, v in self.learner.status().items()]
        elif self.arm is not None and not self.learned:
            out.append(('learning', 'off'))
        if self.verdict:
            out.append(('learned model', self.verdict))
        return out

    def _stop_learning(self) -> None:
        learner, self.learner = self.learner, None
        if learner is not None:
            learner.stop()

    def close(self) -> None:
        """Stop the background build (its checkpoints stay: a restart resumes it)."""
        with self._lock:
            self._stop_learning()
