"""The package's stages import only earlier stages: the import-linter contracts of pyproject.toml."""
from pathlib import Path

from importlinter.cli import lint_imports

ROOT = Path(__file__).resolve().parents[1]


def test_stages_import_only_earlier_stages(tmp_path):
    code = lint_imports(config_filename=str(ROOT / "pyproject.toml"),
                        cache_dir=str(tmp_path), no_logo=True)
    assert code == 0, "an import breaks the layers of pyproject.toml's [tool.importlinter] (see above)"
