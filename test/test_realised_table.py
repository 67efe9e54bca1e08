"""Tables that mark the indices their decoder realises: the build, the manifest, the checks."""

import json
import subprocess
import sys

import numpy as np
import pytest
from served import check_served

from sik_ros.defaults import TableConfig
from sik_ros.errors import CorruptArtifact, InvalidArgument
from sik_ros.learning.indexing import mark_realised
from sik_ros.tables.index_table import IndexTable
from sik_ros.tables.prior_table import PriorTable


def three_cells():
    """A table of three cells holding 3, 2 and 1 indices."""
    pos = np.array([[0.01, 0.01, 0.01]] * 3 + [[0.31, 0.01, 0.01]] * 2 + [[0.61, 0.01, 0.01]])
    z = np.array([[0.0], [1.0], [2.0], [5.0], [6.0], [9.0]])
    return IndexTable.build(z, pos, TableConfig(0.1, 0.5, 4),
                            {'robot': {'robot': 'x'}, 'model': {'m': 1}})


def test_the_look_up_by_position_gives_the_realised_rows_and_each_cells_best(tmp_path):
    """Rows above the threshold are left out of the look-up by position, not out of the table.

    A cell whose rows all miss keeps its best one. The manifest records the threshold, the
    probe distance and the rows marked, through a save and a load.
    """
    table = three_cells()
    errors = np.array([0.001, 0.05, 0.002, 0.04, 0.03, 0.2])
    marked = mark_realised(table, errors, 0.01)
    for t in (marked, IndexTable.load(marked.save(tmp_path / 'r.npz'))):
        assert len(t.indices) == 6
        assert t.realised.tolist() == [True, False, True, False, True, True]
        assert sorted(t.indices[t.rows_near(np.full(3, 0.01), 1), 0].tolist()) == [0.0, 2.0]
        assert t.indices[t.rows_near(np.array([0.31, 0.01, 0.01]), 1), 0].tolist() == [6.0]
        assert len(t.rows_in_cells(np.full(3, 0.01), 1)) == 3
        assert t.manifest['realised'] == {'max_tip_error': 0.01, 'probe': 0.1, 'entries': 4}


def test_a_realised_table_pools_more_cells_for_as_many_rows():
    """``pool_cells`` scales the cells by the share of rows marked (none marked: as is)."""
    table = three_cells()
    assert table.pool_cells(8) == 8
    marked = mark_realised(table, np.array([0.0, 1.0, 1.0, 0.0, 1.0, 0.0]), 0.5)
    assert marked.pool_cells(8) == 16 and marked.pool_cells(1) == 2
    assert PriorTable(4, 8).pool_cells(8) == 8


def test_a_bad_realised_entry_or_an_empty_cell_is_refused(tmp_path):
    """A file whose realised rows disagree with its manifest, or a cell without any, is refused."""
    marked = mark_realised(three_cells(), np.zeros(6), 0.01)
    for bad in ({'max_tip_error': -1.0, 'probe': 0.1, 'entries': 6},
                {'max_tip_error': 0.01, 'probe': 0.1, 'entries': 2},
                {'max_tip_error': 0.01}, 'yes', None):
        marked.manifest = dict(marked.manifest, realised=bad)
        with pytest.raises(CorruptArtifact, match='realised'):
            IndexTable.load(marked.save(tmp_path / 'bad.npz'))
    table = three_cells()
    lonely = IndexTable(table.centers, table.offsets, table.indices,
                        dict(table.manifest, realised={'max_tip_error': 0.01, 'probe': 0.1,
                                                       'entries': 3}),
                        realised=np.array([True, True, True, False, False, False]))
    with pytest.raises(CorruptArtifact, match='realised'):
        IndexTable.load(lonely.save(tmp_path / 'lonely.npz'))
    empty = IndexTable(table.centers, np.array([0, 3, 3, 6]), table.indices, table.manifest)
    with pytest.raises(CorruptArtifact, match='sizes'):
        IndexTable.load(empty.save(tmp_path / 'empty.npz'))
    with pytest.raises(InvalidArgument):
        TableConfig(max_tip_error=-0.01)


def test_build_marks_the_indices_the_decoder_realises(tiny_bundle, uniform_small, panda):
    """Every marked row's decoded tip is within the threshold at its probes, or its cell's best.

    The tip errors' centre probe is the FK of the decoded postures; a pose-goal model, or a
    table without postures, cannot be filtered.
    """
    from sik_ros.learning.checkpoints import load_checkpoint, model_from_checkpoint
    from sik_ros.learning.indexing import build_table, tip_errors
    ckpt = load_checkpoint(tiny_bundle / 'sik_position.pt')
    full = build_table(ckpt, panda, uniform_small, TableConfig(cell=0.08))
    model, _, norm = model_from_checkpoint(ckpt)
    errors = tip_errors(model, norm, full, panda, full.postures)
    tips, _ = panda.fk_batch(full.postures.astype(np.float64))
    centre = np.linalg.norm(tips - full.cell_centers(np.arange(len(full.indices))), axis=1)
    assert np.all(errors >= centre - 1e-9)
    limit = float(np.median(errors))
    marked = build_table(ckpt, panda, uniform_small,
                         TableConfig(cell=0.08, max_tip_error=limit))
    np.testing.assert_array_equal(marked.indices, full.indices)
    assert 0 < marked.manifest['realised']['entries'] < len(full.indices)
    assert marked.manifest['realised']['max_tip_error'] == limit
    # the rule, cell by cell: a row within the limit, or its cell's row of least error
    expected = np.zeros(len(errors), dtype=bool)
    for c in range(len(marked)):
        lo, hi = int(marked.offsets[c]), int(marked.offsets[c + 1])
        assert hi > lo
        for r in range(lo, hi):
            expected[r] = errors[r] <= limit or errors[r] == min(errors[lo:hi])
        assert expected[lo:hi].any()
    assert len(marked) >= 2 and 0 < expected.sum() < len(expected)
    np.testing.assert_array_equal(marked.realised, expected)
    assert marked.manifest['realised']['entries'] == int(expected.sum())
    with pytest.raises(InvalidArgument, match='postures'):
        build_table(ckpt, panda, uniform_small, TableConfig(max_tip_error=0.01), postures=False)
    with pytest.raises(InvalidArgument):
        build_table(load_checkpoint(tiny_bundle / 'sik_pose.pt'), panda, uniform_small,
                    TableConfig(max_tip_error=0.01))


@pytest.mark.e2e
def test_sik_index_records_the_threshold_and_the_bundle_serves(
        tiny_bundle, uniform_small, tmp_path, panda):
    """sik-index --max-tip-error writes the threshold into the table; the bundle answers."""
    from sik_ros.solver import SelectiveIK
    r = subprocess.run([sys.executable, '-m', 'sik_ros.cli.index', '--model',
                        str(tiny_bundle / 'sik_position.pt'), '--dataset',
                        str(uniform_small.path), '--out', str(tmp_path / 't.npz'),
                        '--max-tip-error', '0.2', '--bundle', str(tmp_path / 'b'), '--quiet'],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    table = IndexTable.load(tmp_path / 'b' / 'sik_position_table.npz')
    assert json.loads(json.dumps(table.manifest))['realised']['max_tip_error'] == 0.2
    assert table.realised is not None and table.realised.any()
    target = panda.fk_batch(np.asarray(uniform_small.q[:1]))[0][0]
    ik = SelectiveIK.load(tmp_path / 'b')
    for refine in (True, False):
        assert check_served(panda, ik.solve(target, num_solutions=4, refine=refine), target) >= 1


def test_the_report_describes_a_model_and_its_realised_indices():
    """sik-eval's model line says how the checkpoint was trained and what its table marks."""
    from sik_ros.eval.histories import TrainedModel
    from sik_ros.eval.report import model_line
    h = TrainedModel([{'val_dist_mean_m': 0.0161, 'val_orient_mean_deg': 11.13}], 9000, 2720.0,
                     {'latent_dim': 4, 'encoder': (8,), 'decoder': (8,)},
                     {'batch_size': 8192, 'sampler': 'uniform', 'init': 'a.pt'})
    manifest = {'cells': 2, 'entries': 6, 'realised': {'max_tip_error': 0.015, 'probe': 0.05,
                                                       'entries': 4}}
    line = model_line('pose', h, manifest)
    for words in ('4 elements', '9000 steps of 8192', 'fresh samples', 'earlier model',
                  '1.61 cm', '11.1°', '6 indices in 2 cells', '4 of them realised', '1.5 cm'):
        assert words in line, (words, line)
    assert 'realised' not in model_line('position', h, {'cells': 2, 'entries': 6})
