"""Figures of the evaluation report: arm postures in 3D, error against radius, training curves.

Figures are drawn on matplotlib's Agg canvas directly (no pyplot, no global state) and written
as PNG files atomically (:func:`sik_ros.artifacts.atomic_write`).
"""

from pathlib import Path
from typing import Dict, List, Optional, Sequence, Tuple

from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from mpl_toolkits.mplot3d.art3d import Poly3DCollection
import numpy as np
from scipy.spatial.transform import Rotation

from sik_ros.artifacts import atomic_write
from sik_ros.eval.metrics import arm_points
from sik_ros.kinematics.collision import Obstacle
from sik_ros.kinematics.robot import Robot

#: Colours of several postures in one picture.
COLORS = ('tab:blue', 'tab:orange', 'tab:green', 'tab:purple', 'tab:brown', 'tab:pink',
          'tab:gray', 'tab:olive', 'tab:cyan', 'navy')


def new_figure(width: float, height: float) -> Figure:
    """A figure on an Agg canvas [inches]."""
    fig = Figure(figsize=(width, height), dpi=100)
    FigureCanvasAgg(fig)
    return fig


def save_figure(fig: Figure, path: Path) -> Path:
    """Write a figure as PNG atomically, creating its folder; returns ``path``."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_write(path) as tmp:
        fig.savefig(tmp, format='png')
    return path


# -- arms -----------------------------------------------------------------------------------------

def fit_view(points: np.ndarray, margin: float = 0.05) -> Tuple[np.ndarray, float]:
    """Centre and half-size of a cube holding points (..., 3) and the base [m]."""
    pts = np.concatenate([np.asarray(points, dtype=float).reshape(-1, 3), np.zeros((1, 3))])
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    return (lo + hi) / 2, float((hi - lo).max()) / 2 + margin


def _setup_3d(ax, center: Sequence[float] = (0.0, 0.0, 0.45), half: float = 0.55,
              axes: bool = True, zoom: float = 1.0) -> None:
    """Equal-aspect axes around the given cube, with a faint table square at z = 0."""
    cx, cy, cz = center
    ax.set_xlim(cx - half, cx + half)
    ax.set_ylim(cy - half, cy + half)
    ax.set_zlim(cz - half, cz + half)
    ax.set_box_aspect((1, 1, 1), zoom=zoom)
    sq = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1], [-1, -1]]) * half
    ax.plot(sq[:, 0] + cx, sq[:, 1] + cy, 0 * sq[:, 0], color='0.75', lw=0.6)
    if axes:
        ax.set_xlabel('x [m]', fontsize=7)
        ax.set_ylabel('y [m]', fontsize=7)
        ax.set_zlabel('z [m]', fontsize=7)
        ax.tick_params(labelsize=6)
    else:
        ax.set_axis_off()
    ax.view_init(elev=20, azim=-60)


def draw_arm(ax, robot: Robot, q: np.ndarray, color: str = 'tab:blue', alpha: float = 1.0,
             lw: float = 2.0, label: Optional[str] = None) -> None:
    """The arm as a polyline: base origin, joint origins (dots) and tip."""
    pts = arm_points(robot, q)[0]
    ax.plot(pts[:, 0], pts[:, 1], pts[:, 2], '-', color=color, alpha=alpha, lw=lw, label=label)
    ax.scatter(pts[1:-1, 0], pts[1:-1, 1], pts[1:-1, 2], color=color, alpha=alpha, s=6)


def draw_target(ax, position: Sequence[float], size: float = 30) -> None:
    """The target as a red dot."""
    ax.scatter([position[0]], [position[1]], [position[2]], color='red', s=size, zorder=10)


def draw_box(ax, box: Obstacle, color: str = 'tab:red', alpha: float = 0.25) -> None:
    """A box obstacle (any orientation) as translucent faces."""
    c = np.asarray(box.position, dtype=float)
    h = np.asarray(box.dimensions, dtype=float) / 2
    rot = Rotation.from_quat(box.quaternion).as_matrix()
    corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
    v = c + (corners * h) @ rot.T
    faces = [[0, 1, 3, 2], [4, 5, 7, 6], [0, 1, 5, 4], [2, 3, 7, 6], [0, 2, 6, 4], [1, 3, 7, 5]]
    ax.add_collection3d(Poly3DCollection([v[f] for f in faces], facecolor=color, alpha=alpha,
                                         edgecolor='0.3', linewidth=0.5))


#: One row of :func:`posture_grid`: its label, postures (k, n), target and captions.
Row = Tuple[str, np.ndarray, Sequence[float], Sequence[str]]


def posture_grid(robot: Robot, rows: List[Row], path: Path, title: str = '',
                 cell: float = 1.5) -> Path:
    """A grid of small pictures, one posture each, like the paper's tables of images.

    Args:
        rows: per row ``(label, qs (k, n), target (3,), captions (k,))``.
        path: the PNG file.
        title: figure title.
        cell: size of one picture [inches].
    """
    ncols = max(len(r[1]) for r in rows)
    center, half = fit_view(np.concatenate(
        [arm_points(robot, r[1]).reshape(-1, 3) for r in rows]
        + [np.atleast_2d(r[2]) for r in rows]))
    label_w = 0.3 + 0.09 * max(len(r[0]) for r in rows)  # room for the row labels [in]
    width = cell * ncols + label_w
    fig = new_figure(width, cell * len(rows) + 0.5)
    for i, (label, qs, target, captions) in enumerate(rows):
        for j, q in enumerate(qs):
            ax = fig.add_subplot(len(rows), ncols, i * ncols + j + 1, projection='3d')
            _setup_3d(ax, center, half, axes=False, zoom=1.25)
            draw_arm(ax, robot, q, COLORS[j % len(COLORS)], lw=1.6)
            draw_target(ax, target, size=12)
            ax.set_title(captions[j], fontsize=7, pad=0)
            if j == 0:
                ax.text2D(-0.05, 0.5, label, transform=ax.transAxes, fontsize=9,
                          fontweight='bold', va='center', ha='right')
    fig.suptitle(title, fontsize=10)
    fig.subplots_adjust(left=label_w / width, right=0.99, bottom=0.01,
                        top=1 - 0.45 / (cell * len(rows) + 0.5), wspace=0.02, hspace=0.15)
    return save_figure(fig, path)


def obstacle_figure(robot: Robot, q_first: np.ndarray, q_chosen: np.ndarray, box: Obstacle,
                    goal: Sequence[float], path: Path, captions: Sequence[str]) -> Path:
    """The first unconstrained solution (hitting the box) beside the one Algorithm 2 chose."""
    fig = new_figure(9, 4.5)
    goal = np.asarray(goal, dtype=float)
    corners = np.asarray(box.position) + np.array([-0.5, 0.5])[:, None] * max(box.dimensions)
    pts = arm_points(robot, np.stack([q_first, q_chosen])).reshape(-1, 3)
    center, half = fit_view(np.concatenate([pts, corners, goal[None]]))
    panels = ((q_first, 'tab:red', captions[0]), (q_chosen, 'tab:green', captions[1]))
    for k, (q, color, cap) in enumerate(panels):
        ax = fig.add_subplot(1, 2, k + 1, projection='3d')
        _setup_3d(ax, center, half)
        draw_box(ax, box)
        draw_arm(ax, robot, q, color, lw=2.5)
        draw_target(ax, goal)
        ax.set_title(cap, fontsize=9)
    return save_figure(fig, path)


# -- curves ---------------------------------------------------------------------------------------

def error_vs_radius(radii_cm: Sequence[float], ours: Dict[str, Sequence[float]],
                    paper: Dict[str, Sequence[float]], path: Path,
                    paper_radii_cm: Optional[Sequence[float]] = None) -> Path:
    """Mean distance error [cm] against the radius [cm]: ours solid, the paper's dashed.

    Labels start with the model's name (``SIK raw``, ``SIK refined``, ``FCN``): a model keeps
    one colour across our variants and the paper's line.
    """
    fig = new_figure(8, 4.8)
    ax = fig.add_subplot()
    colors: Dict[str, str] = {}
    markers = ('o', 's', '^', 'v', 'D')
    seen: Dict[str, int] = {}
    for name, vals in ours.items():
        model = name.split(' ')[0]
        color = colors.setdefault(model, COLORS[len(colors) % len(COLORS)])
        k = seen[model] = seen.get(model, -1) + 1
        ax.plot(radii_cm, vals, '-', marker=markers[k % len(markers)], ms=3,
                color=color, label=f'{name} (ours)')
    for name, vals in paper.items():
        color = colors.setdefault(name.split(' ')[0], COLORS[len(colors) % len(COLORS)])
        ax.plot(paper_radii_cm or radii_cm, vals, '--', lw=1, color=color, label=f'{name} (paper)')
    ax.set_yscale('log')
    ax.set_xlabel('radius around the base [cm]')
    ax.set_ylabel('mean distance error [cm]')
    ax.grid(True, which='both', alpha=0.3)
    ax.legend(fontsize=7, ncol=2)
    fig.tight_layout()
    return save_figure(fig, path)


#: Axis labels of history keys.
HISTORY_LABELS = {'loss': 'training loss (per model kind: not comparable across kinds)',
                  'val_dist_mean_m': 'validation distance error [cm]',
                  'val_orient_mean_deg': 'validation orientation error [deg]'}


def training_curves(histories: Dict[str, List[Dict]], path: Path,
                    keys: Sequence[str] = ('loss', 'val_dist_mean_m')) -> Path:
    """Training curves from checkpoint histories: one panel per key, one line per run."""
    fig = new_figure(5 * len(keys), 3.8)
    for k, key in enumerate(keys):
        ax = fig.add_subplot(1, len(keys), k + 1)
        for i, (name, hist) in enumerate(histories.items()):
            pts = [(h['step'], h[key]) for h in hist if key in h and h[key] is not None]
            if not pts:
                continue
            steps, vals = zip(*pts)
            scale = 100.0 if key.endswith('_m') else 1.0
            ax.plot(steps, np.asarray(vals) * scale, 'o-', ms=3, label=name,
                    color=COLORS[i % len(COLORS)])
        ax.set_xlabel('step')
        ax.set_ylabel(HISTORY_LABELS.get(key, key), fontsize=8)
        ax.set_yscale('log')
        ax.grid(True, which='both', alpha=0.3)
        ax.legend(fontsize=7)
    fig.tight_layout()
    return save_figure(fig, path)
