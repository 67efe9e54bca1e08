"""A KD-tree whose k-nearest look-up is one compiled call (the seed table's look-up).

The tree splits a node's box at the middle of its widest side (sliding the cut to the nearest
point when one side would be empty), down to leaves of ``leaf_size`` rows; its points are stored
in leaf order, so that a leaf's rows lie together in memory. A look-up walks it depth first,
the nearer child first, and skips a node whose box is farther than the k-th nearest point found
so far (divided by ``1 + eps``: with ``eps`` > 0 each point returned is within ``1 + eps`` times
the true k-th nearest distance, as scipy's ``cKDTree.query``). A quaternion key and its negative
are one rotation: :func:`nearest_rows` can look up a second key into the same k nearest, a point
counting at its distance to the nearer key.
"""

from typing import Dict, Tuple

from numba import njit
import numpy as np

from sik_ros.kernels._cache import CACHE


@njit('Tuple((int64[::1], int64[::1], int64[::1], float64[::1], int64[::1], int64[::1], '
      'float64[:, ::1], float64[:, ::1], int64))(float64[:, ::1], int64)', cache=CACHE,
      nogil=True)
def tree_build(points, leaf_size):  # pragma: no cover (compiled)
    """The tree of ``points`` (N, d): (order, start, end, split, dim, child, low, high, depth).

    ``order``: the points' rows in leaf order; per node its rows ``order[start:end]``, its cut
    (``dim``, ``split``; ``dim`` -1 for a leaf), its first child's index ``child`` (the second
    is ``child + 1``) and its box (``low``, ``high``, (nodes, d)); ``depth``: the deepest node's.
    """
    n, d = points.shape
    order = np.arange(n)
    cap = 2 * (n // max(leaf_size, 1) + 1) * 2 + 1
    start = np.empty(cap, dtype=np.int64)
    end = np.empty(cap, dtype=np.int64)
    split = np.zeros(cap)
    dim = np.full(cap, -1, dtype=np.int64)
    child = np.full(cap, -1, dtype=np.int64)
    low = np.empty((cap, d))
    high = np.empty((cap, d))
    level = np.zeros(cap, dtype=np.int64)
    start[0], end[0] = 0, n
    count, deepest = 1, 0
    todo = np.empty(cap, dtype=np.int64)
    todo[0] = 0
    top = 1
    while top > 0:
        top -= 1
        node = todo[top]
        a, b = start[node], end[node]
        for c in range(d):
            low[node, c], high[node, c] = np.inf, -np.inf
        for i in range(a, b):
            r = order[i]
            for c in range(d):
                v = points[r, c]
                if v < low[node, c]:
                    low[node, c] = v
                if v > high[node, c]:
                    high[node, c] = v
        deepest = max(deepest, level[node])
        if b - a <= leaf_size or count + 2 > cap:
            continue
        widest, width = 0, -1.0
        for c in range(d):
            if high[node, c] - low[node, c] > width:
                widest, width = c, high[node, c] - low[node, c]
        if width <= 0.0:
            continue  # every row the same point: a leaf
        cut = 0.5 * (low[node, widest] + high[node, widest])
        i, j = a, b - 1
        while i <= j:  # rows below the cut to the front (rows in place stay: a tree built
            if points[order[i], widest] < cut:  # on its own leaf order keeps that order)
                i += 1
            elif points[order[j], widest] >= cut:
                j -= 1
            else:
                order[i], order[j] = order[j], order[i]
                i += 1
                j -= 1
        if i == a:  # none below: the lowest row alone on the low side
            m = a
            for s in range(a, b):
                if points[order[s], widest] < points[order[m], widest]:
                    m = s
            order[a], order[m] = order[m], order[a]
            i = a + 1
            cut = points[order[a], widest]
        dim[node], split[node], child[node] = widest, cut, count
        for side in range(2):
            c = count + side
            start[c] = a if side == 0 else i
            end[c] = i if side == 0 else b
            level[c] = level[node] + 1
            todo[top] = c
            top += 1
        count += 2
    return (order, start[:count].copy(), end[:count].copy(), split[:count].copy(),
            dim[:count].copy(), child[:count].copy(), low[:count].copy(), high[:count].copy(),
            deepest)


@njit(cache=CACHE, nogil=True)
def _sift_down(heap_d, heap_r, size, i):  # pragma: no cover (compiled)
    """Restore the max-heap after its entry ``i`` became smaller."""
    while True:
        left = 2 * i + 1
        if left >= size:
            return
        big = left
        if left + 1 < size and heap_d[left + 1] > heap_d[left]:
            big = left + 1
        if heap_d[big] <= heap_d[i]:
            return
        heap_d[i], heap_d[big] = heap_d[big], heap_d[i]
        heap_r[i], heap_r[big] = heap_r[big], heap_r[i]
        i = big


@njit(cache=CACHE, nogil=True)
def _walk(tree, key, eps, heap, size, k, unique):  # pragma: no cover (compiled)
    """Push the rows near ``key`` into the max-heap (``size`` filled of ``k``); the new size.

    ``tree``: ``(points, nodes, split, low, high, depth)``; ``heap``: ``(heap_d, heap_r)``.

    A node's distance from ``key`` is bounded below by the offsets from its box, carried down
    the walk (a far child's offset along the cut is the distance to the cut), so the walk reads
    only the cuts, not every node's box. ``unique``: a row already in the heap is not pushed
    again, but takes the nearer distance (the second key's walk).
    """
    points, nodes, split, low, high, depth = tree
    heap_d, heap_r = heap
    d = key.shape[0]
    stack = np.empty(depth + 2, dtype=np.int64)
    bounds = np.empty(depth + 2)
    offsets = np.empty((depth + 2, d))
    s = 0.0
    for c in range(d):
        v = 0.0
        if key[c] < low[c]:
            v = low[c] - key[c]
        elif key[c] > high[c]:
            v = key[c] - high[c]
        offsets[0, c] = v
        s += v * v
    stack[0], bounds[0] = 0, s
    top = 1
    scale = 1.0 / ((1.0 + eps) * (1.0 + eps))
    while top > 0:
        top -= 1
        node = stack[top]
        if size == k and bounds[top] > heap_d[0] * scale:
            continue
        c = nodes[node, 0]
        if c < 0:
            for r in range(nodes[node, 2], nodes[node, 3]):
                s = 0.0
                for a in range(d):
                    v = np.float64(points[r, a]) - key[a]
                    s += v * v
                if size == k and s >= heap_d[0]:
                    continue
                if unique:
                    seen = -1
                    for h in range(size):
                        if heap_r[h] == r:
                            seen = h
                            break
                    if seen >= 0:  # nearer this key than the other: its nearer distance
                        if s < heap_d[seen]:
                            heap_d[seen] = s
                            _sift_down(heap_d, heap_r, size, seen)
                        continue
                if size < k:  # fill: sift the new leaf up
                    i = size
                    heap_d[i], heap_r[i] = s, r
                    size += 1
                    while i > 0 and heap_d[(i - 1) // 2] < heap_d[i]:
                        p = (i - 1) // 2
                        heap_d[i], heap_d[p] = heap_d[p], heap_d[i]
                        heap_r[i], heap_r[p] = heap_r[p], heap_r[i]
                        i = p
                else:
                    heap_d[0], heap_r[0] = s, r
                    _sift_down(heap_d, heap_r, size, 0)
            continue
        diff = key[c] - split[node]
        near = nodes[node, 1] + (1 if diff >= 0.0 else 0)
        far = nodes[node, 1] + (0 if diff >= 0.0 else 1)
        # the far child (below the near one on the stack): offset along the cut to the cut
        bound = bounds[top]
        for a in range(d):
            offsets[top + 1, a] = offsets[top, a]
        stack[top], bounds[top] = far, bound - offsets[top, c] ** 2 + diff * diff
        offsets[top, c] = abs(diff)
        stack[top + 1], bounds[top + 1] = near, bound
        top += 2
    return size


@njit(cache=CACHE, nogil=True)
def nearest_rows(points, nodes, split, low, high, depth, columns, key, other, k,
                 eps):  # pragma: no cover (compiled)
    """The ``k`` rows of ``points`` nearest ``key``, nearest first, and their squared distances.

    ``points``, ``nodes``, ``split``, ``low``, ``high``, ``depth``: a :class:`KDTree`'s;
    ``key`` and ``other`` are given in all the columns, of which the tree keeps ``columns``.
    ``other``: a second key (empty: none) looked up only where it can be nearer than the k-th
    row found for ``key`` (exactly, without ``eps``); a row counts at its distance to the
    nearer key, once.
    """
    k = min(k, points.shape[0])
    heap_d = np.empty(k)
    heap_r = np.empty(k, dtype=np.int64)
    kept = np.empty(columns.shape[0])
    for c in range(columns.shape[0]):
        kept[c] = key[columns[c]]
    tree = (points, nodes, split, low, high, depth)
    size = _walk(tree, kept, eps, (heap_d, heap_r), 0, k, False)
    if other.shape[0] == key.shape[0] and size > 0:
        for c in range(columns.shape[0]):
            kept[c] = other[columns[c]]
        size = _walk(tree, kept, 0.0, (heap_d, heap_r), size, k, True)
    rank = np.argsort(heap_d[:size], kind='mergesort')
    rows = np.empty(size, dtype=np.int64)
    dist = np.empty(size)
    for i in range(size):
        rows[i] = heap_r[rank[i]]
        dist[i] = heap_d[rank[i]]
    return rows, dist


#: The argument types of a look-up's tree (the :class:`KDTree` arrays) in kernel signatures.
TREE_TYPES = 'float32[:, ::1], int32[:, ::1], float64[::1], float64[::1], float64[::1], int64, ' \
    'int64[::1]'


@njit('Tuple((int64[::1], float64[::1]))(' + TREE_TYPES + ', float64[::1], float64[::1], '
      'int64, float64)', cache=CACHE, nogil=True)
def tree_nearest(points, nodes, split, low, high, depth, columns, key, other, k,
                 eps):  # pragma: no cover (compiled)
    """:func:`nearest_rows`, compiled for these types (a call from Python)."""
    return nearest_rows(points, nodes, split, low, high, depth, columns, key, other, k, eps)


class KDTree:
    """Points (N, d) in a compiled KD-tree, stored in leaf order, in single precision.

    A look-up is bound by memory (the rows near a key lie in a few dozen leaves, wherever in
    the table): the points are kept in float32, without the columns every point shares (a seed
    table's keys turned to azimuth 0 all have y = 0), and a node in 24 bytes.

    Attributes:
        points: the points (N, d') in leaf order (``points[i]`` is row ``order[i]`` given),
            float32, the columns ``columns`` of those given.
        order: the given rows' indices in leaf order (N,).
        columns: the given columns kept (those where the points differ).
    """

    def __init__(self, points: np.ndarray, leaf_size: int = 32):
        given = np.asarray(points, dtype=np.float32)
        if given.ndim != 2 or len(given) == 0:
            raise ValueError('a KD-tree needs points (N, d) with N >= 1')
        self.columns = np.flatnonzero(given.min(axis=0) < given.max(axis=0)).astype(np.int64)
        if len(self.columns) == 0:
            self.columns = np.arange(1, dtype=np.int64)
        self._shared = given[0].astype(np.float64)  # the columns left out: every point's
        self._dropped = np.setdiff1d(np.arange(given.shape[1]), self.columns)
        kept = np.ascontiguousarray(given[:, self.columns])
        order, start, end, self._split, dim, child, low, high, self._depth = tree_build(
            kept.astype(np.float64), int(leaf_size))
        # what a look-up reads of a node, together (the boxes stay out of its way)
        self._nodes = np.ascontiguousarray(np.stack([dim, child, start, end], axis=1),
                                           dtype=np.int32)
        self._low, self._high = low[0].copy(), high[0].copy()
        self.order = order
        self.points = np.ascontiguousarray(kept[order])
        self._none = np.empty(0)

    def __len__(self) -> int:
        """Number of points."""
        return len(self.points)

    def nearest(self, key: np.ndarray, k: int, eps: float = 0.0,
                other: np.ndarray = None):
        """The ``k`` points nearest ``key`` (leaf-order rows, nearest first) and their distances.

        ``other``: a second key, looked up where it can be nearer (:func:`nearest_rows`).
        """
        key = np.ascontiguousarray(key, dtype=np.float64)
        rows, dist = tree_nearest(*self.arrays(), key, self._none if other is None else
                                  np.ascontiguousarray(other, dtype=np.float64), int(k),
                                  float(eps))
        # the columns left out add one distance to every point
        return rows, np.sqrt(dist + ((key[self._dropped] - self._shared[self._dropped]) ** 2
                                     ).sum())

    def arrays(self) -> Tuple:
        """The tree as the kernels take it (:data:`TREE_TYPES`)."""
        return (self.points, self._nodes, self._split, self._low, self._high, self._depth,
                self.columns)

    #: The arrays of :meth:`state`, by name.
    STATE = ('points', 'nodes', 'split', 'low', 'high', 'depth', 'columns', 'order', 'shared')

    def state(self) -> Dict[str, np.ndarray]:
        """The built tree as arrays (:data:`STATE`), for :meth:`from_state` to take back."""
        return {'points': self.points, 'nodes': self._nodes, 'split': self._split,
                'low': self._low, 'high': self._high, 'depth': np.array(self._depth),
                'columns': self.columns, 'order': self.order, 'shared': self._shared}

    @classmethod
    def from_state(cls, state: Dict[str, np.ndarray]) -> 'KDTree':
        """The tree of :meth:`state`'s arrays, checked: the kernels read them unchecked.

        Raises:
            ValueError: an array missing or of another type or shape, a node outside the
                tree or its rows, a depth other than its nodes', or an order not a
                permutation of the rows.
        """
        want = {'points': np.float32, 'nodes': np.int32, 'split': np.float64,
                'low': np.float64, 'high': np.float64, 'depth': np.int64,
                'columns': np.int64, 'order': np.int64, 'shared': np.float64}
        for name, dtype in want.items():
            if name not in state or np.asarray(state[name]).dtype != dtype:
                raise ValueError(f'KD-tree: {name} missing or not {np.dtype(dtype)}')
        points, nodes = state['points'], state['nodes']
        n, m = len(points), len(nodes)
        d = len(state['columns'])
        if points.ndim != 2 or points.shape[1] != d or n < 1 or nodes.ndim != 2 \
                or nodes.shape[1] != 4 or m < 1 or state['split'].shape != (m,) \
                or state['low'].shape != (d,) or state['high'].shape != (d,) \
                or state['order'].shape != (n,) or state['shared'].ndim != 1 \
                or np.any(state['columns'] < 0) \
                or np.any(state['columns'] >= len(state['shared'])):
            raise ValueError(f'KD-tree: arrays of disagreeing shapes ({n} points, {m} nodes)')
        dim, child, start, end = (nodes[:, i].astype(np.int64) for i in range(4))
        inner = dim >= 0
        if np.any(dim >= d) or np.any(dim < -1) or np.any(start < 0) or np.any(end > n) \
                or np.any(start > end) or np.any(inner & ((child < 1) | (child + 1 >= m))) \
                or start[0] != 0 or end[0] != n:
            raise ValueError('KD-tree: a node outside the tree or its points')
        level, seen, depth = np.zeros(1, dtype=np.int64), 1, 0
        while True:  # the nodes by depth, from the root: each once, as a tree's
            below = level[inner[level]]
            level = np.concatenate([child[below], child[below] + 1])
            if len(level) == 0:
                break
            depth, seen = depth + 1, seen + len(level)
            if seen > m:
                raise ValueError('KD-tree: its nodes are not a tree')
        if seen != m or int(state['depth']) != depth:
            raise ValueError(f'KD-tree: depth {int(state["depth"])} for nodes {depth} deep')
        if not np.array_equal(np.sort(state['order']), np.arange(n)):
            raise ValueError('KD-tree: its order is not a permutation of its points')
        tree = cls.__new__(cls)
        tree.points = np.ascontiguousarray(points)
        tree._nodes = np.ascontiguousarray(nodes)
        tree._split = np.ascontiguousarray(state['split'])
        tree._low = np.ascontiguousarray(state['low'])
        tree._high = np.ascontiguousarray(state['high'])
        tree._depth = depth
        tree.columns = np.ascontiguousarray(state['columns'])
        tree.order = np.ascontiguousarray(state['order'])
        tree._shared = np.ascontiguousarray(state['shared'])
        tree._dropped = np.setdiff1d(np.arange(len(tree._shared)), tree.columns)
        tree._none = np.empty(0)
        return tree
