"""Bundles: a directory with one model and one index table per goal kind, and ``bundle.json``."""

import os
from pathlib import Path
import shutil
from typing import Dict

from sik_ros.artifacts import FORMAT_VERSION, read_json, write_json_atomic
from sik_ros.errors import ArtifactMismatch


def add_to_bundle(bundle: Path, robot_manifest: Dict, goal: str, model_file: Path,
                  table_file: Path) -> Path:
    """Copy a model and its table into a bundle directory and list them in ``bundle.json``.

    Files are copied under temporary names and renamed; the manifest is rewritten atomically
    last, so a reader never sees a manifest naming a half-written file.
    """
    bundle = Path(bundle)
    bundle.mkdir(parents=True, exist_ok=True)
    manifest_path = bundle / 'bundle.json'
    if manifest_path.exists():
        manifest = read_json(manifest_path, f'bundle {bundle}')
        if manifest['robot'] != robot_manifest:
            raise ArtifactMismatch(f'bundle {bundle}: robot', manifest['robot'], robot_manifest)
    else:
        manifest = {'kind': 'sik_bundle', 'format_version': FORMAT_VERSION,
                    'robot': robot_manifest, 'models': {}}
    names = {'model': f'sik_{goal}.pt', 'table': f'sik_{goal}_table.npz'}
    for key, src in (('model', model_file), ('table', table_file)):
        dst = bundle / names[key]
        tmp = bundle / f'.{names[key]}.{os.getpid()}.tmp'
        if Path(src).resolve() != dst.resolve():
            shutil.copyfile(src, tmp)
            os.replace(tmp, dst)
    manifest['models'][goal] = names
    write_json_atomic(manifest_path, manifest)
    return bundle
