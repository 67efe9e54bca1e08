"""The browser viewer (viser): the arm's ranked solutions for a target you drag.

One :class:`Viewer` serves one bundle. The page shows the arm's meshes at the solver's ranked
solutions for the target (a draggable frame): one posture at a time or all side by side, each
coloured by its ranking tier, with a table of their errors, clearance and score; box obstacles
to drag about; and a Cartesian path along a line, played back on the arm.
"""

from pathlib import Path
import threading
import time
from typing import List, Optional

import numpy as np

from sik_ros.errors import SikError
from sik_ros.kinematics.collision import Obstacle
from sik_ros.solver import IKResult, SelectiveIK
from sik_ros.viewer.meshes import ArmMeshes
from sik_ros.viewer.scene import (Goal, grid_offsets, joint_text, reach, solution_colors,
                                  solve_goal, solve_line, start_target, table)

ONE_BY_ONE, SIDE_BY_SIDE = 'one by one', 'side by side'
#: Side of a new box obstacle [m].
BOX_SIDE = 0.12
#: Time between the frames of a path played back [s].
PLAY_STEP = 0.08


def xyzw(wxyz) -> np.ndarray:
    """Turn viser's w x y z quaternion into the solver's x y z w."""
    w, x, y, z = (float(v) for v in wxyz)
    return np.array([x, y, z, w])


def wxyz(xyzw_) -> tuple:
    """Turn the solver's x y z w quaternion into viser's w x y z."""
    x, y, z, w = (float(v) for v in xyzw_)
    return (w, x, y, z)


class Viewer:
    """A viser server showing one bundle's solutions.

    Args:
        ik: the solver.
        host: address to serve on.
        port: TCP port.
    """

    def __init__(self, ik: SelectiveIK, host: str = '127.0.0.1', port: int = 8080):
        import viser
        self.ik = ik
        self.meshes = ArmMeshes(ik.robot)
        self.server = viser.ViserServer(host=host, port=port, verbose=False)
        self.server.gui.configure_theme(control_width='large')
        self._lock = threading.Lock()
        self._draw_lock = threading.RLock()  # GUI callbacks draw from viser's threads
        self._dirty = False
        self.result: Optional[IKResult] = None
        #: the goal position [m] that ``result`` answers
        self.result_position: Optional[np.ndarray] = None
        self.path_q: Optional[np.ndarray] = None
        self._obstacles: List[tuple] = []
        self._reach = max(reach(ik), 0.2)
        #: distance between postures shown side by side [m]
        self.spacing = 0.9 * self._reach
        position, quaternion = start_target(ik)
        pose = 'pose' in ik.goals
        self.goal = Goal(position, quaternion if pose else None)
        self._quaternion = quaternion
        self._build_scene(position, quaternion)
        self._build_gui(pose)
        self._frame_grid(16)
        self.update()

    def _frame_grid(self, count: int) -> None:
        """Point the page's first camera at ``count`` postures laid side by side."""
        offsets = grid_offsets(count, self.spacing)
        centre = 0.5 * (offsets.min(0) + offsets.max(0)) + np.array([0, 0, 0.3 * self._reach])
        span = float(np.ptp(offsets, axis=0).max()) + self.spacing
        camera = self.server.initial_camera
        camera.look_at = tuple(centre)
        camera.position = tuple(centre + np.array([0.75, 0.2, 0.55]) * span)

    # -- layout ---------------------------------------------------------------------------------

    def _build_scene(self, position: np.ndarray, quaternion: np.ndarray) -> None:
        scene = self.server.scene
        scene.set_up_direction('+z')
        scene.add_grid('/ground', width=8 * self._reach, height=8 * self._reach,
                       cell_size=0.1, section_size=0.5)
        self.arm = [scene.add_batched_meshes_simple(
            f'/arm/{i:02d}_{p.name}', p.vertices, p.faces, batched_wxyzs=np.array([[1, 0, 0, 0.]]),
            batched_positions=np.zeros((1, 3)), batched_colors=np.array([p.color], np.uint8))
            for i, p in enumerate(self.meshes.parts)]
        size = 0.25 * self._reach
        self.target = scene.add_transform_controls('/target', scale=size, position=position,
                                                   wxyz=wxyz(quaternion))
        self.target.on_update(lambda _: self._target_moved())
        self.path_end = scene.add_transform_controls(
            '/path_end', scale=0.6 * size, disable_rotations=True,
            position=position + np.array([0.0, 0.25 * self._reach, 0.0]), visible=False)
        self.path_end.on_update(lambda _: self._draw_path_line())
        self._labels: list = []

    def _build_gui(self, pose: bool) -> None:
        gui = self.server.gui
        gui.add_markdown(f'**sik_ros** · bundle `{Path(str(self.ik.bundle)).name}` · '
                         f'{self.ik.robot.dof} joints '
                         f'`{self.ik.robot.base_frame}` → `{self.ik.robot.tip_frame}`')
        with gui.add_folder('Goal'):
            kinds = [g for g in ('pose', 'position') if g in self.ik.goals]
            self.kind = gui.add_dropdown('goal', kinds, initial_value=kinds[0])
            self.count = gui.add_slider('solutions', 1, 16, 1, 16)
        with gui.add_folder('Solutions'):
            self.layout = gui.add_dropdown('layout', (SIDE_BY_SIDE, ONE_BY_ONE),
                                           initial_value=SIDE_BY_SIDE)
            self.pick = gui.add_slider('solution', 1, 16, 1, 1)
            self.summary = gui.add_markdown('')
            self.joints = gui.add_markdown('')
        with gui.add_folder('Obstacles', expand_by_default=False):
            add = gui.add_button('add a box')
            clear = gui.add_button('remove all')
        with gui.add_folder('Cartesian path', expand_by_default=False):
            self.show_path = gui.add_checkbox('line to the end marker', False)
            self.waypoints = gui.add_slider('waypoints', 2, 100, 1, 20)
            plan = gui.add_button('plan from the shown solution')
            play = gui.add_button('play')
            self.step = gui.add_slider('waypoint', 1, 2, 1, 1, disabled=True)
            self.path_text = gui.add_markdown('')
        self.kind.on_update(lambda _: self._goal_kind())
        self.count.on_update(lambda _: self.update())
        self.layout.on_update(lambda _: self.draw())
        self.pick.on_update(lambda _: self.draw())
        add.on_click(lambda _: self.add_box())
        clear.on_click(lambda _: self.clear_boxes())
        self.show_path.on_update(lambda _: self._draw_path_line())
        plan.on_click(lambda _: self.plan_path())
        play.on_click(lambda _: self._play())
        self.step.on_update(lambda _: self._show_step())

    # -- solving --------------------------------------------------------------------------------

    def _goal_kind(self) -> None:
        self.goal.orientation = xyzw(self.target.wxyz) if self.kind.value == 'pose' else None
        self.update()

    def _target_moved(self) -> None:
        self.goal.position = np.array(self.target.position, dtype=float)
        if self.kind.value == 'pose':
            self.goal.orientation = xyzw(self.target.wxyz)
        self._draw_path_line()
        self.update()

    def update(self) -> None:
        """Solve for the current goal and draw the answer; a call while one runs is merged."""
        if not self._lock.acquire(blocking=False):
            self._dirty = True
            return
        try:
            while True:
                self._dirty = False
                self.goal.num_solutions = int(self.count.value)
                self.goal.obstacles = [o for o, _, _ in self._obstacles]
                position = np.array(self.goal.position)
                try:
                    self.result = solve_goal(self.ik, self.goal)
                    self.path_q = None
                    self.draw()
                except SikError as exc:
                    self.result = None
                    self.summary.content = f'**{exc}**'
                    self.draw()
                self.result_position = position
                if not self._dirty:
                    break
        finally:
            self._lock.release()

    # -- drawing --------------------------------------------------------------------------------

    def draw(self) -> None:
        """Draw the arm at the current answer in the chosen layout, with its table."""
        with self._draw_lock:
            self._draw()

    def _draw(self) -> None:
        result = self.result
        solutions = result.solutions if result is not None else []
        k = len(solutions)
        self.pick.max = max(k, 1)
        selected = min(int(self.pick.value), max(k, 1)) - 1
        if result is not None:
            self.summary.content = table(result, selected)
        if k == 0:
            self._pose_arm(np.zeros((0, self.ik.robot.dof)), np.zeros((0, 3)),
                           np.zeros((0, 3), np.uint8))
            self.joints.content = ''
            return
        colors = solution_colors(result)
        qs = np.array([s.q for s in solutions])
        self.joints.content = (f'solution {selected + 1}, joints [rad]:\n\n'
                               + joint_text(self.ik.joint_names, qs[selected]))
        if self.layout.value == SIDE_BY_SIDE and self.path_q is None:
            offsets = grid_offsets(k, self.spacing)
            self._pose_arm(qs, offsets, colors)
            self._draw_labels(result, offsets)
        else:
            q = qs[selected] if self.path_q is None else self.path_q[int(self.step.value) - 1]
            self._pose_arm(q[None], np.zeros((1, 3)), colors[selected:selected + 1])
            self._draw_labels(result, None)

    def _pose_arm(self, qs: np.ndarray, offsets: np.ndarray, colors: np.ndarray) -> None:
        rotations, positions = self.meshes.poses_batch(qs)
        with self.server.atomic():
            for j, handle in enumerate(self.arm):
                handle.visible = len(qs) > 0
                if len(qs) == 0:
                    continue
                handle.batched_wxyzs = rotations[:, j].astype(np.float32)
                handle.batched_positions = (positions[:, j] + offsets).astype(np.float32)
                handle.batched_colors = colors

    def _draw_labels(self, result: IKResult, offsets: Optional[np.ndarray]) -> None:
        for label in self._labels:
            label.remove()
        self._labels = []
        if offsets is None:
            return
        for i, (s, offset) in enumerate(zip(result.solutions, offsets)):
            text = (f'{i + 1}: {s.position_error * 1e3:.2f} mm, '
                    f'{np.degrees(s.orientation_error):.2f}°, score {s.score:.3g}')
            self._labels.append(self.server.scene.add_label(
                f'/labels/{i:02d}', text, position=offset + np.array([0, 0, -0.05]),
                font_screen_scale=0.6))
            if i:
                self._labels.append(self.server.scene.add_icosphere(
                    f'/labels/target_{i:02d}', radius=0.02, color=(240, 200, 0),
                    position=self.goal.position + offset))

    # -- obstacles ------------------------------------------------------------------------------

    def add_box(self) -> None:
        """Add a box obstacle beside the goal, movable on the page, and solve again."""
        i = len(self._obstacles)
        center = self.goal.position + np.array([0.15, 0.0, 0.0]) + 0.05 * i
        box = self.server.scene.add_box(f'/obstacles/{i}/box', color=(200, 80, 80),
                                        dimensions=(BOX_SIDE,) * 3, opacity=0.6)
        controls = self.server.scene.add_transform_controls(
            f'/obstacles/{i}', scale=0.15, disable_rotations=True, position=center)
        entry = [Obstacle('box', (BOX_SIDE,) * 3, tuple(center)), box, controls]

        def moved(_) -> None:
            center = tuple(float(v) for v in controls.position)
            entry[0] = Obstacle('box', (BOX_SIDE,) * 3, center)
            self._obstacles[i] = tuple(entry)
            self.update()
        controls.on_update(moved)
        self._obstacles.append(tuple(entry))
        self.update()

    def clear_boxes(self) -> None:
        """Remove every box obstacle and solve again."""
        for _, box, controls in self._obstacles:
            box.remove()
            controls.remove()
        self._obstacles = []
        self.update()

    # -- Cartesian path -------------------------------------------------------------------------

    def _draw_path_line(self) -> None:
        self.path_end.visible = bool(self.show_path.value)
        if not self.show_path.value:
            self.server.scene.add_line_segments('/path_line', np.zeros((1, 2, 3)), (0, 0, 0),
                                                visible=False)
            return
        points = np.array([[self.goal.position, np.array(self.path_end.position)]])
        self.server.scene.add_line_segments('/path_line', points, (240, 200, 0),
                                            thickness=0.006)

    def plan_path(self) -> None:
        """Plan a line from the goal to the end marker, from the shown solution.

        Sets ``path_q`` (the best path's joint values, one row per waypoint [rad]) and the
        path's summary on the page; a failed plan says why there and leaves ``path_q`` as is.
        """
        self.show_path.value = True
        self._draw_path_line()
        seed = None
        if self.result is not None and self.result.solutions:
            seed = self.result.solutions[int(self.pick.value) - 1].q
        try:
            path = solve_line(self.ik, self.goal, np.array(self.path_end.position),
                              int(self.waypoints.value), seed)
        except SikError as exc:
            self.path_text.content = f'**{exc}**'
            return
        if not path.paths:
            self.path_text.content = f'no path ({path.message})'
            return
        best = path.paths[0]
        self.path_q = best.q
        self.step.max = len(best.q)
        self.step.value = 1
        self.step.disabled = False
        self.layout.value = ONE_BY_ONE
        self.path_text.content = (
            f'{"success" if path.success else "partial"}: fraction {path.fraction:.2f}, '
            f'largest step {best.max_step:.3f} rad, travel {best.travel:.2f} rad, clearance '
            f'{best.min_obstacle_distance:.3g} m')
        self.draw()

    def _show_step(self) -> None:
        if self.path_q is not None:
            self.draw()

    def _play(self) -> None:
        if self.path_q is None:
            self.plan_path()
        if self.path_q is None:
            return
        for i in range(1, len(self.path_q) + 1):
            self.step.value = i
            time.sleep(PLAY_STEP)
