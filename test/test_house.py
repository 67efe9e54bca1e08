"""The package's floors (docs/interfaces.md, section 1) hold in every module's imports."""

import ast
from pathlib import Path
from typing import Dict, List, Set, Tuple

REPO = Path(__file__).resolve().parents[1]
PACKAGE = REPO / 'sik_ros'
INTERFACES = REPO / 'docs' / 'interfaces.md'
#: The floors down the chain: a module imports from its own floor and the tiers before it;
#: the floors of one tier stand side by side and import nothing of each other.
TIERS = (('root',), ('kernels',), ('kinematics',), ('tables',), ('learning',), ('bundles',),
         ('solver base',), ('solver.families',), ('solver',), ('serving',),
         ('ros', 'eval', 'viewer'), ('cli',))
RANK = {floor: rank for rank, tier in enumerate(TIERS) for floor in tier}
#: The solver's base, below its families package: settings, the goal's context, candidates,
#: results, objectives, refinement, the networks, restarts and scores.
SOLVER_BASE = ('batch', 'codec', 'config', 'context', 'explore', 'objectives', 'refine',
               'results', 'scores')
#: Modules whose floor is not their folder's: the solver's objectives, named at the top, and
#: the solver's base.
FLOOR_OF = {'sik_ros.objectives': 'solver',
            **{f'sik_ros.solver.{m}': 'solver base' for m in SOLVER_BASE}}
#: Packages inside a folder with a floor of their own.
SUBFLOORS = {'sik_ros.solver.families': 'solver.families'}
#: Imports that reach down the chain and are known (none: every one is a failure).
KNOWN_DOWNWARD = set()


def module_name(path: Path) -> str:
    """``sik_ros/solver/path/__init__.py`` -> ``sik_ros.solver.path``."""
    parts = list(path.relative_to(REPO).with_suffix('').parts)
    return '.'.join(parts[:-1] if parts[-1] == '__init__' else parts)


MODULES: Dict[str, Path] = {module_name(p): p for p in sorted(PACKAGE.rglob('*.py'))}


def folder(module: str) -> str:
    """A module's folder under ``sik_ros/``: ``root`` for the package's own modules."""
    parts = module.split('.')
    return parts[1] if len(parts) > 1 and (PACKAGE / parts[1]).is_dir() else 'root'


def floor(module: str) -> str:
    """A module's floor: its folder's, but where :data:`FLOOR_OF` or :data:`SUBFLOORS` say."""
    for package, name in SUBFLOORS.items():
        if module == package or module.startswith(package + '.'):
            return name
    return FLOOR_OF.get(module, folder(module))


def lazy_exports(package: str) -> Dict[str, str]:
    """A package's ``_EXPORTS`` (public name -> its module), read from its ``__init__``."""
    path = MODULES.get(package)
    if path is None or path.name != '__init__.py':
        return {}
    for node in ast.parse(path.read_text()).body:
        if isinstance(node, ast.Assign) and any(
                isinstance(t, ast.Name) and t.id == '_EXPORTS' for t in node.targets):
            return ast.literal_eval(node.value)
    return {}


def known_module(name: str) -> str:
    """The longest leading part of a dotted name that is a module of the package."""
    while name not in MODULES:
        name = name.rpartition('.')[0]
    return name


def imports(module: str) -> Set[str]:
    """The package's modules that ``module`` imports, at module level or inside a function.

    ``from package import name`` counts as an import of the module that defines ``name`` when
    the package loads it lazily (``_EXPORTS``), and of the submodule when ``name`` is one.
    """
    path = MODULES[module]
    package = module if path.name == '__init__.py' else module.rpartition('.')[0]
    found = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            found |= {known_module(a.name) for a in node.names if a.name.startswith('sik_ros')}
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ''
            if node.level:
                above = package.split('.')[:len(package.split('.')) - node.level + 1]
                base = '.'.join(above + ([base] if base else []))
            if base != 'sik_ros' and not base.startswith('sik_ros.'):
                continue
            lazy = lazy_exports(base)
            for alias in node.names:
                sub = f'{base}.{alias.name}'
                found.add(sub if sub in MODULES else lazy.get(alias.name, known_module(base)))
    found.discard(module)
    return found


GRAPH: Dict[str, Set[str]] = {m: imports(m) for m in MODULES}


def downward(graph: Dict[str, Set[str]]) -> Set[Tuple[str, str]]:
    """The imports of a floor further down the chain, or of a floor beside the importer's."""
    return {(m, t) for m, targets in graph.items() for t in targets
            if floor(m) != floor(t) and RANK[floor(t)] >= RANK[floor(m)]}


def cycles(graph: Dict[str, Set[str]]) -> List[List[str]]:
    """The strongly connected sets of two or more modules (Tarjan's algorithm)."""
    index: Dict[str, int] = {}
    low: Dict[str, int] = {}
    stack: List[str] = []
    found: List[List[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            group = []
            while True:
                w = stack.pop()
                group.append(w)
                if w == v:
                    break
            if len(group) > 1:
                found.append(sorted(group))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def table_row(module: str) -> str:
    """The floor table's row that names ``module``: its floor's, the root's for a root module."""
    return 'root' if folder(module) == 'root' else floor(module)


def floor_rows() -> Dict[str, str]:
    """The floor table of docs/interfaces.md, section 1: floor -> its row, in order."""
    section = INTERFACES.read_text().split('## 1.', 1)[1].split('\n## ', 1)[0]
    table = section.split('| floor | holds |', 1)[1]
    rows = {}
    for line in table.splitlines()[2:]:
        if not line.startswith('|'):
            break
        first = line.split('|')[1].strip()
        if first.startswith('root'):
            name = 'root'
        else:  # `solver/families/` -> solver.families; `solver/`, its base -> solver base
            name = first.split('`')[1].rstrip('/').replace('/', '.')
            name += ' base' if first.endswith('its base') else ''
        rows[name] = line
    return rows


def test_the_graph_holds_every_module_and_its_imports():
    """The walk reads every module, function-level imports and lazy exports included."""
    assert len(MODULES) > 100
    assert sum(len(t) for t in GRAPH.values()) > 500
    # an import inside a function, and names the solver package loads lazily
    assert 'sik_ros.learning.training' in GRAPH['sik_ros.bundles.build_training']
    assert 'sik_ros.solver.selective_ik' in GRAPH['sik_ros.eval.baselines']
    assert 'sik_ros.bundles.bundle' in GRAPH['sik_ros.eval.baselines']


def test_no_module_imports_a_floor_further_down():
    """No module imports a floor further down the chain than its own, or one beside it."""
    assert set(RANK) == {floor(m) for m in MODULES}
    found = downward(GRAPH)
    assert not found - KNOWN_DOWNWARD, 'imports down the chain:\n' + '\n'.join(
        f'{m} ({floor(m)}) -> {t} ({floor(t)})' for m, t in sorted(found - KNOWN_DOWNWARD))
    assert not KNOWN_DOWNWARD - found, (
        f'gone, delete them from KNOWN_DOWNWARD: {sorted(KNOWN_DOWNWARD - found)}')


def test_the_check_sees_an_import_down_the_chain():
    """A kernel importing the solver, a solver module importing the node, are caught."""
    graph = {'sik_ros.kernels.dls': {'sik_ros.solver.refine'},
             'sik_ros.solver.refine': {'sik_ros.ros.node', 'sik_ros.kernels.dls'},
             'sik_ros.eval.run': {'sik_ros.viewer.scene', 'sik_ros.solver.refine'},
             'sik_ros.cli.view': {'sik_ros.viewer.scene', 'sik_ros.eval.run'}}
    assert downward(graph) == {('sik_ros.kernels.dls', 'sik_ros.solver.refine'),
                               ('sik_ros.solver.refine', 'sik_ros.ros.node'),
                               ('sik_ros.eval.run', 'sik_ros.viewer.scene')}
    # the solver's base below its families package, the package below the rest of the solver
    graph = {'sik_ros.solver.refine': {'sik_ros.solver.families.membership'},
             'sik_ros.solver.families.search': {'sik_ros.solver.ranking',
                                                'sik_ros.solver.scores'},
             'sik_ros.solver.ranking': {'sik_ros.solver.families.membership'}}
    assert downward(graph) == {('sik_ros.solver.refine', 'sik_ros.solver.families.membership'),
                               ('sik_ros.solver.families.search', 'sik_ros.solver.ranking')}


def test_no_import_cycles():
    """No modules import each other, directly or through others."""
    assert cycles({'a': {'b'}, 'b': {'c'}, 'c': {'a'}, 'd': {'a'}}) == [['a', 'b', 'c']]
    assert cycles(GRAPH) == []


def test_the_floor_table_follows_the_chain_and_names_every_module():
    """docs/interfaces.md's floor table lists the floors in order and each module in its row."""
    rows = floor_rows()
    assert list(rows) == [f for tier in TIERS for f in tier]
    named = [p for m, p in MODULES.items() if not p.name.startswith('_')]
    assert len(named) > 100
    missing = [str(p.relative_to(PACKAGE)) for p in named
               if f'`{p.name}`' not in rows[table_row(module_name(p))]]
    assert not missing, f'modules the floor table of docs/interfaces.md does not name: {missing}'
