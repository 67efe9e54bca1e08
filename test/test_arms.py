"""Any arm: loading, default frames, periodic joints, budgets, sik-build, 2 pi equivalents."""

import json
import os
from pathlib import Path
import shutil
import subprocess
import sys

import numpy as np
import pinocchio as pin
import pytest

from sik_ros.errors import ArtifactMismatch, InvalidModel
from sik_ros.kinematics.robot import Robot
from sik_ros.kinematics.robots import (build_model, chain_differences, load_robot,
                                       robot_from_manifest)
from sik_ros.solver import SelectiveIK
from sik_ros.solver.config import SAME_BRANCH
from sik_ros.solver.context import Goal
from sik_ros.solver.ranking import posture_mask
from sik_ros.solver.refine import refine
from sik_ros.tables.dataset import grid_count

pytestmark = pytest.mark.slow

CLI = [sys.executable, '-m']


def test_a_six_joint_arm_with_whole_turn_joints_loads_with_default_frames(ur5):
    """The UR5 loads by name alone: base = parent link of the first joint, tip = tool0."""
    assert (ur5.dof, ur5.base_frame, ur5.tip_frame) == (6, 'base_link', 'tool0')
    assert ur5.periodic.all()
    q = np.random.default_rng(0).uniform(ur5.lower, ur5.upper, (20, 6))
    p, _ = ur5.fk_rot(q)
    ref = np.array([ur5.pin_placement(qi).translation for qi in q])
    assert np.abs(p - ref).max() < 1e-9


def test_a_finger_robot_gets_default_frames_from_its_finger_joints():
    """Joints named like a gripper's are the chain when there is nothing else (TriFinger edu)."""
    finger = load_robot('finger_edu')
    assert (finger.dof, finger.base_frame, finger.tip_frame) == (
        3, 'finger_base_link', 'finger_tip_link')


def test_continuous_joints_become_periodic_and_keep_the_kinematics():
    """Kinova's continuous joints: revolute over +-2 pi, periodic, FK equal to the original's."""
    import example_robot_data as erd
    kinova = load_robot('kinova')
    assert kinova.dof == 6 and kinova.tip_frame == 'j2s6s200_end_effector'
    assert kinova.periodic.tolist() == [True, False, False, True, False, True]
    assert np.allclose(kinova.upper[kinova.periodic], 2 * np.pi)
    original = erd.load('kinova').model  # continuous joints: (cos, sin) per joint
    data = original.createData()
    frame = original.getFrameId('j2s6s200_end_effector')
    base = original.getFrameId('j2s6s200_link_base')
    for q in np.random.default_rng(1).uniform(kinova.lower, kinova.upper, (10, 6)):
        full = pin.neutral(original)
        for name, value in zip(kinova.joint_names, q):
            j = original.getJointId(name)
            i = original.joints[j].idx_q
            if original.joints[j].nq == 2:
                full[i:i + 2] = np.cos(value), np.sin(value)
            else:
                full[i] = value
        pin.framesForwardKinematics(original, data, full)
        ref = data.oMf[base].actInv(data.oMf[frame]).translation
        assert np.allclose(kinova.fk(q)[0], ref, atol=1e-9)


def test_grid_sweeps_periodic_joints_over_one_turn(ur5, panda):
    """A periodic joint is swept over one turn: UR5 at 30 deg is 12^6 rows, the Panda unchanged."""
    assert grid_count(ur5.lower, ur5.upper, 30.0, ur5.periodic) == 12 ** 6
    assert grid_count(panda.lower, panda.upper, 30.0, panda.periodic) == 6_967_296


def test_a_floating_root_is_locked(ur5):
    """A free-flyer root (as mobile and legged models load) is locked: same chain, same FK."""
    model = pin.buildModelFromUrdf(str(ur5.urdf_path), pin.JointModelFreeFlyer())
    floating = Robot('ur5', ur5.urdf_path, model, 'base_link', 'tool0')
    assert floating.joint_names == ur5.joint_names
    q = np.random.default_rng(2).uniform(ur5.lower, ur5.upper, (5, 6))
    assert np.allclose(floating.fk_rot(q)[0], ur5.fk_rot(q)[0], atol=1e-12)


def test_an_ambiguous_frame_name_resolves_to_the_body():
    """SO-100 has a link and a joint both called 'gripper': the link is the tip, no raw error."""
    so100 = load_robot('so100', tip='gripper')
    assert so100.tip_frame == 'gripper' and so100.dof == 5
    q = np.zeros(5)
    assert np.allclose(so100.fk(q)[0], so100.pin_placement(q).translation)


def test_arm_joints_named_like_their_links_keep_their_names(tmp_path, ur5):
    """A URDF whose arm joints share their child links' names (ANYmal C does so): it loads.

    Pinocchio's model reduction (a gripper joint to lock) refused such names with a raw
    ValueError; the joints keep their names, the links answer to them as frames.
    """
    text = ur5.urdf_path.read_text()
    # the third: a joint already called what a renaming would call the second
    pairs = [('shoulder_pan_joint', 'shoulder_link'), ('elbow_joint', 'forearm_link'),
             ('wrist_1_joint', 'forearm_link_joint')]
    for joint, link in pairs:
        text = text.replace(f'"{joint}"', f'"{link}"')
    gripper = ('<link name="finger"/><joint name="finger_joint" type="prismatic">'
               '<parent link="tool0"/><child link="finger"/><axis xyz="1 0 0"/>'
               '<limit lower="0" upper="0.04" effort="1" velocity="1"/></joint></robot>')
    urdf = tmp_path / 'arm.urdf'
    urdf.write_text(text.replace('</robot>', gripper))
    robot = load_robot('x', str(urdf), tip='tool0')
    assert robot.dof == 6 and robot.joint_names[0] == 'shoulder_link'
    assert robot.joint_names[2:4] == ['forearm_link', 'forearm_link_joint']
    frame = robot.model.frames[robot.model.getFrameId('forearm_link', pin.FrameType.BODY)]
    assert robot.model.names[frame.parentJoint] == 'forearm_link'
    q = np.random.default_rng(3).uniform(ur5.lower, ur5.upper, (5, 6))
    assert np.allclose(robot.fk_rot(q)[0], ur5.fk_rot(q)[0], atol=1e-12)
    assert np.allclose(robot.fk_rot(q)[0], [robot.pin_placement(qi).translation for qi in q])


def test_a_prismatic_joint_in_the_chain_is_refused_by_name():
    """A tip past the Panda's finger joint: refused with the joint named, in one line."""
    with pytest.raises(InvalidModel, match="panda_finger_joint1.*prismatic") as info:
        load_robot('panda', tip='panda_leftfinger')
    assert '\n' not in str(info.value)


def test_meshes_of_a_urdf_in_a_package_folder_are_found(tmp_path, ur5):
    """A URDF in ``src/<pkg>/urdf/`` finds its ``package://<pkg>/`` collision meshes."""
    package = tmp_path / 'src' / 'example-robot-data'
    (package / 'urdf').mkdir(parents=True)
    (package / 'robots').symlink_to(ur5.urdf_path.parents[2])
    urdf = package / 'urdf' / 'arm.urdf'
    shutil.copyfile(ur5.urdf_path, urdf)
    assert load_robot('x', str(urdf)).collision_model.ngeoms == ur5.collision_model.ngeoms


@pytest.mark.e2e
def test_sik_build_refuses_missing_meshes_before_collecting(tmp_path, ur5):
    """Collision meshes that cannot be found: exit 2, one line naming the mesh, nothing made."""
    urdf = tmp_path / 'arm.urdf'
    shutil.copyfile(ur5.urdf_path, urdf)
    out = tmp_path / 'bundle'
    run = subprocess.run(CLI + ['sik_ros.cli.build', '--urdf', str(urdf), '--out', str(out),
                                '--quiet'], capture_output=True, text=True, timeout=120,
                         env={**os.environ, 'ROS_PACKAGE_PATH': ''})
    assert run.returncode == 2
    lines = run.stderr.strip().splitlines()
    assert len(lines) == 1 and 'collision/base.stl' in lines[0], lines
    assert 'ROS_PACKAGE_PATH' in lines[0]
    assert sorted(p.name for p in tmp_path.iterdir()) == ['arm.urdf']


@pytest.mark.e2e
def test_sik_collect_refuses_a_grid_over_its_budget_before_writing(tmp_path):
    """Over --max-rows: exit 2, one line naming what would fit, nothing written."""
    out = tmp_path / 'ds'
    run = subprocess.run(CLI + ['sik_ros.cli.collect', '--robot', 'ur5', '--interval', '10',
                                '--max-rows', '1000000', '--out', str(out), '--quiet'],
                         capture_output=True, text=True, timeout=120)
    assert run.returncode == 2
    lines = run.stderr.strip().splitlines()
    assert len(lines) == 1 and 'budget' in lines[0], lines
    assert '--interval 36 (1,000,000 rows)' in lines[0], lines
    assert '--sampler uniform' in lines[0]
    assert not out.exists() and list(tmp_path.iterdir()) == []


def test_a_urdf_that_changed_is_refused(tmp_path, ur5):
    """An artifact made from a URDF file is refused once that file changes or moves."""
    urdf = tmp_path / 'arm.urdf'
    shutil.copyfile(ur5.urdf_path, urdf)
    robot = load_robot('x', str(urdf))
    manifest = robot.manifest()
    assert manifest['urdf'] == str(urdf.resolve())
    assert robot_from_manifest(manifest).joint_names == ur5.joint_names
    urdf.write_text(urdf.read_text().replace('velocity="3.15"', 'velocity="3.0"', 1))
    with pytest.raises(ArtifactMismatch, match='changed'):
        robot_from_manifest(manifest)
    urdf.unlink()
    with pytest.raises(ArtifactMismatch, match='moved'):
        robot_from_manifest(manifest)


def test_chain_differences_name_what_differs(ur5):
    """A robot_description that differs from the bundle's chain is told apart, and how."""
    text = Path(ur5.urdf_path).read_text()
    assert chain_differences(ur5, text) == []
    moved = text.replace('xyz="0.0 0.0 0.089159"', 'xyz="0.0 0.0 0.1"', 1)
    assert chain_differences(ur5, moved) == ["joint placements differ at ['shoulder_pan_joint']"]
    limited = text.replace('upper="6.28318530718"', 'upper="3.0"', 1)
    assert chain_differences(ur5, limited) == [
        "joint upper limits differ at ['shoulder_pan_joint']"]


def test_sik_build_makes_a_bundle_that_solves_with_2pi_equivalents(ur5_bundle, ur5):
    """sik-build: a bundle with its self-check; FK-verified, distinct, with 2 pi equivalents."""
    out, stdout = ur5_bundle
    manifest = json.loads((out / 'bundle.json').read_text())
    assert set(manifest['models']) == {'position', 'pose'}
    assert 'seeds' in manifest['models']['pose']  # six joints: a seed table for the branches
    assert manifest['self_check']['position']['targets'] == 20
    assert 'self-check, position goals' in stdout and 'tip tool0' in stdout
    ik = SelectiveIK.load(out)
    rng = np.random.default_rng(5)
    for goal in ('position', 'pose'):
        for q in rng.uniform(ur5.lower, ur5.upper, (5, 6)):
            p, quat = ur5.fk(q)
            res = ik.solve(p, quat if goal == 'pose' else None, num_solutions=64)
            assert res.success
            free = [s for s in res.solutions if s.converged and not s.in_collision]
            qs = np.array([s.q for s in free])
            assert np.all(qs >= ur5.lower - 1e-9) and np.all(qs <= ur5.upper + 1e-9)
            reached, rot = ur5.fk_rot(qs)
            assert np.linalg.norm(reached - p, axis=1).max() <= 1e-4
            d = np.linalg.norm(qs[:, None] - qs[None], axis=2) + np.eye(len(qs)) * 9
            # distinct: two branches of a pose are never merged as near postures
            assert d.min() >= (SAME_BRANCH if goal == 'pose' else 0.5)
            # by the solver's own rule too (position goals: without the tool-roll joint)
            assert posture_mask(ik.context, qs, goal).all()
            if goal == 'pose':  # a pose has a few branches: their 2 pi equivalents follow them
                wrapped = np.angle(np.exp(1j * (qs[:, None] - qs[None])))
                same = np.all(np.abs(wrapped) < 1e-3, axis=2) & ~np.eye(len(qs), dtype=bool)
                assert same.any()
                # every distinct posture ranks before a second equivalent of one
                repeat = np.array([same[i, :i].any() for i in range(len(qs))])
                assert np.all(repeat[np.argmax(repeat):]), repeat
    # the seed picks the nearest equivalent: a solution turned by 2 pi is found as it is
    p, quat = ur5.fk(np.array([0.3, -1.0, 1.2, -1.5, 1.2, 0.5]))
    best = ik.solve(p, quat, num_solutions=8).solutions[0].q
    j = int(np.argmax(ur5.upper - np.abs(best)))  # a joint with room to turn
    seed = best.copy()
    seed[j] += 2 * np.pi if best[j] + 2 * np.pi <= ur5.upper[j] else -2 * np.pi
    first = ik.solve(p, quat, num_solutions=8, seed=seed).solutions[0].q
    assert np.abs(first - seed).max() < 1e-3, (first, seed)


def test_sik_build_starts_the_pose_model_from_the_position_model(ur5_bundle):
    """sik-build starts the pose model from the position model's checkpoint (bundle.json says so).

    The pose model keeps the position model's index size and starts part way through the
    position model's training (its start, time and the position model's step then stated in
    bundle.json), from that checkpoint, with the pose recipe.
    """
    from sik_ros.learning.checkpoints import load_checkpoint
    out, stdout = ur5_bundle
    training = json.loads((out / 'bundle.json').read_text())['training']
    assert training['position']['init'] == '' and training['pose']['init'] == 'position'
    pose, position = training['pose'], training['position']
    assert 0 < pose['start_s'] < position['seconds']
    assert abs(pose['start_s'] + pose['seconds'] - position['seconds']) < 1.0
    assert 0 < pose['init_step'] <= position['steps']
    assert 'from the position model after' in stdout
    models = {g: load_checkpoint(out / f'sik_{g}.pt') for g in ('position', 'pose')}
    assert models['pose']['train_config']['init'] == 'run_pose/start.pt'
    assert models['pose']['model_config']['latent_dim'] == \
        models['position']['model_config']['latent_dim']
    assert models['pose']['train_config']['cycle_weight'] > 0


def test_build_model_reads_a_plain_urdf(ur5):
    """The URDF reader gives Pinocchio's model (revolute joints as they are)."""
    model = build_model(ur5.urdf_path)
    assert [model.joints[j].shortname() for j in range(1, model.njoints)][:2] == [
        'JointModelRZ', 'JointModelRY']


def test_position_path_starts_take_the_turns_nearest_the_seed(ur5_bundle, ur5):
    """A position path's table postures take the 2 pi turns nearest the seed.

    Each periodic joint within its limits, as a brute force over the turns finds.
    """
    from sik_ros.kinematics.periodic import nearest_turns
    from sik_ros.solver.path import starts
    ik = SelectiveIK.load(ur5_bundle[0])
    rng = np.random.default_rng(3)
    for q in rng.uniform(ur5.lower, ur5.upper, (5, 6)):
        seed = rng.uniform(ur5.lower, ur5.upper)
        near = starts.table_near_seed(ik.context, Goal(ur5.fk(q)[0]), seed, 4)
        assert len(near)
        for row in near:
            for j in range(6):
                turns = row[j] + 2 * np.pi * np.arange(-2, 3)
                turns = turns[(turns >= ur5.lower[j] - 1e-9) & (turns <= ur5.upper[j] + 1e-9)]
                assert abs(row[j] - seed[j]) <= np.abs(turns - seed[j]).min() + 1e-9
        np.testing.assert_array_equal(nearest_turns(ik.robot, near, seed), near)


def test_refinement_turns_a_periodic_joint_back_at_its_limit(ur5_bundle, ur5):
    """A periodic joint stepping past its limit comes back by 2 pi; a path's steps clamp.

    The start's wrist joint is 0.3 rad short of the goal's, turned by 2 pi to 6.2 rad, near
    its 2 pi limit: refinement reaches the goal with that joint at the goal's own value (a
    clamp at 2 pi held it there). Following a path (no joint may jump) still clamps.
    """
    from sik_ros.kernels.dls import limited_step
    ik = SelectiveIK.load(ur5_bundle[0])
    goal_q = np.array([0.4, -1.2, 1.1, 0.217, 1.3, 0.6])
    p, rot = ur5.fk_rot(goal_q[None])
    start = goal_q.copy()
    start[3] = 0.217 + 2 * np.pi - 0.3
    assert start[3] < ur5.upper[3]
    r = refine(ik.context, start[None], Goal(p[0], rot[0]))
    q, perr, oerr = r.q, r.perr, r.oerr
    assert perr[0] <= 1e-4 and oerr[0] <= 1e-3
    assert abs(q[0, 3] - 0.217) < 1e-3 and np.all(q[0] <= ur5.upper)
    # one step on the wrist joint alone, past the limit: turned back, or clamped
    jac = np.zeros((6, 6))
    jac[5, 3] = 1.0
    err = np.array([0, 0, 0, 0, 0, 0.3])
    work = np.empty((6, 6)), np.empty((6, 6)), np.empty(6)
    turned, clamped = start[None].copy(), start[None].copy()
    for row, turn in ((turned[0], True), (clamped[0], False)):
        limited_step(row, jac, err, 6, (ur5.lower, ur5.upper, ur5.periodic), turn,
                     (1e-6, ik.config.max_step), work)
    assert turned[0, 3] == pytest.approx(0.217, abs=1e-3)
    assert clamped[0, 3] == ur5.upper[3]


def test_distinct_rows_with_periodic_joints_are_apart_however_turned():
    """With ``periodic``, rows a whole turn apart are one posture; others by their distance."""
    from sik_ros.solver.scores import distinct_mask
    periodic = np.array([True, True, False])
    q = np.array([[0.1, 3.0, 0.0],
                  [0.1 + 2 * np.pi, 3.0 - 2 * np.pi, 0.0],   # the first, turned: dropped
                  [0.1, -3.1, 0.3],                         # 0.35 rad away, turned: dropped
                  [0.1, 3.0, 0.6]])                         # 0.6 rad away: kept
    np.testing.assert_array_equal(distinct_mask(q, 0.5), [True, True, True, True])
    np.testing.assert_array_equal(distinct_mask(q, 0.5, periodic=periodic),
                                  [True, False, False, True])
    # the last joint left out (a tool roll at position goals): the last row joins the first
    np.testing.assert_array_equal(distinct_mask(q, 0.5, True, periodic),
                                  [True, False, False, False])
