"""sik-eval: a quick run writes a report with numbers and figures, and its numbers are true."""

import json
from pathlib import Path
import re

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from sik_ros.cli.eval import main
from sik_ros.eval import Baseline, load_baselines, position_errors
from sik_ros.learning.checkpoints import export_model
from sik_ros.learning.models import ModelConfig, PRESETS
from sik_ros.learning.train_config import TrainConfig
from sik_ros.learning.training import Trainer
from sik_ros.solver import SelectiveIK
from sik_ros.tables.prior_table import PriorTable

pytestmark = pytest.mark.slow

PNG_MAGIC = b'\x89PNG\r\n\x1a\n'


def train_baseline(robot, dataset, kind, out):
    """Train a tiny position model of ``kind`` for a few steps; export it as ``out/<kind>.pt``."""
    cfg = ModelConfig(kind=kind, encoder=PRESETS['tiny'][0], decoder=PRESETS['tiny'][1])
    t = Trainer(robot, dataset, cfg,
                TrainConfig(steps=20, batch_size=256, warmup=5, eval_every=20,
                            checkpoint_every=20, val_rows=500, fk_weight=0.0), out / f'run_{kind}')
    t.run()
    return export_model(t.checkpoint(), out / f'{kind}.pt')


@pytest.fixture(scope='module')
def baselines(panda, uniform_small, tmp_path_factory):
    """A folder with a tiny FCN (trained for a few steps) as the only baseline."""
    out = tmp_path_factory.mktemp('baselines')
    train_baseline(panda, uniform_small, 'fcn', out)
    return out


@pytest.fixture(scope='module')
def report(tiny_bundle, baselines, tmp_path_factory):
    """The output folder of one ``sik-eval --quick`` run on the tiny bundle."""
    out = tmp_path_factory.mktemp('eval')
    rc = main(['--quick', '--bundle', str(tiny_bundle), '--baselines', str(baselines),
               '--out', str(out), '--targets', '3', '--samples', '20000', '--quiet'])
    assert rc == 0
    return out


def radius_table(text):
    """The per-radius table of results.md as (header, rows of cells)."""
    rows = []
    for line in text.split('<!-- per-radius table -->\n', 1)[1].splitlines():
        if not line.startswith('|'):
            break
        rows.append([c.strip() for c in line.strip('|').split('|')])
    return rows[0], [r for r in rows[2:] if r[0] != 'average']


def test_report_and_figures_are_written(report):
    """results.md, results.json and every PNG the report links to exist and are PNG files."""
    text = (report / 'results.md').read_text()
    links = re.findall(r'!\[[^\]]*\]\(([^)]+\.png)\)', text)
    assert len(links) >= 5
    for link in links:
        assert (report / link).read_bytes()[:8] == PNG_MAGIC, link
    assert json.loads((report / 'results.json').read_text())['quick'] is True
    assert not list(report.glob('**/.*.tmp*'))
    for section in ('## 1.', '## 2.', '## 3.', '## 4.', '## 5.', '## 6.'):
        assert section in text
    assert 'PSIK: not provided' in text and 'ANFIS: not provided' in text
    assert '### The indices of SIK and PSIK: range and interpolation' in text
    assert '### Raw pose answers of the product' in text
    assert "### The pose model by the paper's protocol" in text


def pin_position_errors(robot, q, target):
    """Distance errors [m] of configurations (N, n) by Pinocchio's FK, computed here."""
    return np.array([np.linalg.norm(robot.pin_placement(qi).translation - target)
                     for qi in np.atleast_2d(q)])


def paper_protocol_errors(ik, target, minimum=10):
    """The paper's protocol recomputed: the nearest cells' indices decoded, all counted."""
    from sik_ros.solver.codec import decode
    from sik_ros.solver.context import Goal
    table = ik.models['position'].table
    order = np.argsort(np.linalg.norm(table.centers - target, axis=1), kind='stable')
    rows = []
    for cell in order:
        cell_rows = np.arange(table.offsets[cell], table.offsets[cell + 1])
        if table.realised is not None:
            cell_rows = cell_rows[table.realised[cell_rows]]
        rows.extend(cell_rows.tolist())
        if len(rows) >= minimum:
            break
    q = decode(ik.context, Goal(target), table.indices[np.array(rows)])
    return pin_position_errors(ik.robot, q, target)


def test_tables_contain_numbers(report):
    """The per-radius, timing and diversity tables hold finite numbers, not placeholders.

    The paper's figures stand beside the paper's protocol only: the product's answers have a
    table of their own without a paper column.
    """
    text = (report / 'results.md').read_text()
    header, rows = radius_table(text)
    assert header[:4] == ['radius [cm]', 'targets', 'SIK ours', 'SIK paper']
    assert len(rows) == 4
    for row in rows:
        for name in ('SIK ours', 'SIK paper', 'FCN ours'):
            assert np.isfinite(float(row[header.index(name)])), (name, row)
    product = text.split("### The product's answers (not the paper's protocol)", 1)[1]
    product = product.split('\n## ', 1)[0].split('\n### ', 1)[0]
    assert '| model | answer | workspace mean [cm] |' in product and 'paper' not in \
        product.split('| model | answer |', 1)[1].split('\n', 1)[0]
    assert 'as good or better' not in product
    assert re.search(r'\| SIK refined: `solve\(num_solutions=1\)` \| \d+\.\d+ \|', text)
    assert re.search(r'\| a \| ours raw( \| \d+\.\d+){7} \|', text)


def test_radius_errors_match_fk_recomputation(report, tiny_bundle, baselines):
    """Per-radius errors in results.md and results.json equal a fresh computation by FK.

    SIK's column is the paper's protocol (every looked-up index decoded, none dropped), FCN's
    its one prediction; the product's best raw answer is in results.json.
    """
    text = (report / 'results.md').read_text()
    header, rows = radius_table(text)
    data = json.loads((report / 'results.json').read_text())
    ik = SelectiveIK.load(tiny_bundle)
    fcn = Baseline('fcn', baselines / 'fcn.pt', ik.robot)
    assert len(rows) == 4
    for row in rows:
        radius = float(row[0]) / 100
        entry = data['radius'][str(radius)]
        targets = np.array(entry['targets'])
        assert len(targets) == 3
        assert np.all(np.abs(np.linalg.norm(targets, axis=1) - radius) < 0.01)
        looked = [paper_protocol_errors(ik, p) for p in targets]
        assert all(len(e) >= 10 for e in looked)
        assert entry['errors_m']['sik']['lookup_count'] == [len(e) for e in looked]
        assert float(row[header.index('SIK ours')]) == pytest.approx(
            100 * np.mean([e.mean() for e in looked]), abs=0.006)
        raw = [pin_position_errors(ik.robot, ik.solve(p, num_solutions=10, refine=False)
                                   .solutions[0].q, p)[0] for p in targets]
        np.testing.assert_allclose(entry['errors_m']['sik']['raw_first'], raw, rtol=1e-5,
                                   atol=1e-7)
        fcn_err = [pin_position_errors(ik.robot, q, p)[0]
                   for q, p in zip(fcn.predict(targets), targets)]
        assert float(row[header.index('FCN ours')]) == pytest.approx(
            100 * np.mean(fcn_err), abs=0.006)


def test_index_properties_count_their_pairs_and_check_them_by_fk(tiny_bundle):
    """The index study decodes as many pairs as asked at every target, errors by FK.

    Its spread is the table's; a pair of one index twice has its midpoint on the endpoints:
    the same error and no detour.
    """
    from sik_ros.eval.index_properties import index_properties, midpoints
    from sik_ros.eval.studies import workspace_targets
    ik = SelectiveIK.load(tiny_bundle)
    targets, _ = workspace_targets(ik.robot, 4, seed=0)
    props = index_properties(ik, targets, pairs=3)
    assert props.targets == 4
    assert sorted(props.pairs) == ['adjacent', 'random']
    for m in props.pairs.values():
        assert len(m.endpoint_err) == 24 and len(m.midpoint_err) == len(m.detour) == 12
        assert np.all(np.isfinite(m.midpoint_err)) and np.all(m.detour >= 0)
    z = np.asarray(ik.models['position'].table.indices, dtype=float)
    np.testing.assert_allclose(props.std, z.std(0), rtol=1e-6)
    same = midpoints(ik, targets[0], z[:2], z[:2])
    np.testing.assert_allclose(same.midpoint_err, same.endpoint_err[:2], atol=1e-6)
    assert np.all(same.detour == 0.0)


def test_shipped_baselines_load_and_a_damaged_one_is_refused(panda, baselines, tmp_path):
    """A shipped folder serves its models; a file changed after shipping is refused by name."""
    from sik_ros.eval.shipped import MANIFEST, ship_baselines
    out = ship_baselines(tmp_path / 'shipped', {'fcn': baselines / 'fcn.pt'}, None,
                         panda.manifest())
    assert sorted(p.name for p in out.iterdir()) == sorted([MANIFEST, 'fcn.pt'])
    found, missing = load_baselines(out, panda)
    assert list(found) == ['fcn'] and missing['anfis'].startswith('not provided')
    data = bytearray((out / 'fcn.pt').read_bytes())
    data[-1] ^= 0xFF
    (out / 'fcn.pt').write_bytes(bytes(data))
    found, missing = load_baselines(out, panda)
    assert 'fcn' not in found and 'does not match its sha256' in missing['fcn']


def test_raw_pose_study_without_self_collision_leaves_the_solver_as_it_was(tiny_bundle):
    """The unchecked copy finds no self-collision; every error is the answers' FK error."""
    from sik_ros.eval.raw_pose import raw_pose_study, SEED, without_self_collision
    ik = SelectiveIK.load(tiny_bundle)
    folded = np.zeros((1, ik.robot.dof))
    folded[0, 3] = ik.robot.lower[3]  # elbow fully bent: the forearm meets the upper arm
    assert ik.checker.self_collision(folded)[0]
    unchecked = without_self_collision(ik)
    assert not unchecked.checker.self_collision(folded)[0]
    assert ik.checker.self_collision(folded)[0]
    study = raw_pose_study(ik, targets=3)
    assert sorted(study) == ['shipped', 'unchecked']
    q = np.random.default_rng(SEED).uniform(ik.robot.lower, ik.robot.upper, (3, ik.robot.dof))
    goals = [ik.robot.pin_placement(qi) for qi in q]
    for name, solver in (('shipped', ik), ('unchecked', unchecked)):
        r = study[name]
        assert len(r.distance) == len(r.angle) == len(r.free) == 3
        for i, goal in enumerate(goals):
            quat = Rotation.from_matrix(goal.rotation).as_quat()
            sols = solver.solve(goal.translation, quat, num_solutions=10, refine=False).solutions
            assert len(sols) >= 1
            reached = [ik.robot.pin_placement(s.q) for s in sols]
            dist = [np.linalg.norm(p.translation - goal.translation) for p in reached]
            angle = [Rotation.from_matrix(goal.rotation.T @ p.rotation).magnitude()
                     for p in reached]
            assert r.distance[i] == pytest.approx(np.mean(dist), rel=1e-5, abs=1e-7)
            assert r.angle[i] == pytest.approx(np.mean(angle), rel=1e-4, abs=1e-6)


def test_a_refused_shipped_baseline_stops_the_evaluation(panda, tiny_bundle, baselines,
                                                         tmp_path, capsys):
    """A shipped model that fails its manifest exits 2 with one line; no report is written."""
    from sik_ros.eval.shipped import ship_baselines
    out = ship_baselines(tmp_path / 'shipped', {'fcn': baselines / 'fcn.pt'}, None,
                         panda.manifest())
    data = bytearray((out / 'fcn.pt').read_bytes())
    data[-1] ^= 0xFF
    (out / 'fcn.pt').write_bytes(bytes(data))
    rc = main(['--quick', '--bundle', str(tiny_bundle), '--baselines', str(out),
               '--out', str(tmp_path / 'eval'), '--quiet'])
    assert rc == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and 'fcn' in err[0] and 'refused' in err[0]
    assert not (tmp_path / 'eval' / 'results.md').exists()


def test_the_baselines_shipped_with_the_panda_bundle_load(panda):
    """Every baseline shipped in the repository matches its manifest and loads for the Panda."""
    from sik_ros.eval.shipped import check_shipped
    folder = Path(__file__).resolve().parents[1] / 'sik_ros' / 'bundles' / 'panda' / 'baselines'
    assert check_shipped(folder) == {}
    found, missing = load_baselines(folder, panda)
    assert sorted(found) == ['anfis', 'fcn', 'fcn_uni', 'psik'] and missing == {}
    assert isinstance(found['psik'], SelectiveIK)
    assert not isinstance(found['psik'].models['position'].table, PriorTable)


def test_missing_folder_is_refused(tiny_bundle, tmp_path, capsys):
    """A --baselines folder that does not exist exits non-zero with a one-line reason."""
    rc = main(['--quick', '--bundle', str(tiny_bundle), '--out', str(tmp_path),
               '--baselines', str(tmp_path / 'nope'), '--quiet'])
    assert rc == 2
    assert 'not a directory' in capsys.readouterr().err
    assert not Path(tmp_path / 'results.md').exists()


def test_psik_without_table_solves_and_is_reported(tiny_bundle, panda, uniform_small, tmp_path):
    """A PSIK model given alone (``psik.pt``): its prior-draw table serves every solve."""
    train_baseline(panda, uniform_small, 'psik', tmp_path)
    out = tmp_path / 'eval'
    rc = main(['--quick', '--bundle', str(tiny_bundle), '--baselines', str(tmp_path),
               '--out', str(out), '--targets', '1', '--samples', '20000', '--quiet'])
    assert rc == 0
    text = (out / 'results.md').read_text()
    assert f'- PSIK: `{tmp_path / "psik.pt"}` (no index table given' in text
    header, rows = radius_table(text)
    assert len(rows) == 4
    for row in rows:
        for name in ('PSIK ours', 'PSIK paper'):
            assert np.isfinite(float(row[header.index(name)])), (name, row)
    assert re.search(r'\| PSIK raw: `solve\(refine=False, num_solutions=1\)` \| \d+\.\d+ \|', text)
    assert '### PSIK: distance errors [cm] (paper Table 4)' in text
    data = json.loads((out / 'results.json').read_text())
    assert 'psik_raw_1' in data['timing_ms'] and len(data['diversity']['psik']) == 4
    found, missing = load_baselines(tmp_path, panda)
    psik = found['psik']
    assert isinstance(psik.models['position'].table, PriorTable) and 'psik' not in missing
    targets = np.array(data['workspace']['targets'])
    reported_all = data['workspace']['errors_m']['psik']['raw_first']
    assert len(targets) == len(reported_all) == 1
    for p, reported in zip(targets, reported_all):
        sols = psik.solve(p, num_solutions=10, refine=False).solutions
        assert sols
        errors = position_errors(panda, np.array([s.q for s in sols]), p)
        assert np.all(np.isfinite(errors))
        assert errors[0] == pytest.approx(reported, rel=1e-5, abs=1e-7)
        assert psik.solve(p, num_solutions=1).solutions


def test_verdicts_compare_with_the_paper_and_a_small_margin():
    """Worse beyond 5 %, on a par within it, as good or better at or below the paper."""
    from sik_ros.eval.markdown import verdict
    assert 'worse than the paper' in verdict(0.60, 0.50, 'cm', 'x')
    assert 'on a par' in verdict(0.51, 0.50, 'cm', 'x')
    assert 'as good or better' in verdict(0.50, 0.50, 'cm', 'x')
    assert 'not measured' in verdict(float('nan'), 0.50, 'cm', 'x')
