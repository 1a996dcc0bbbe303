"""bench/this_tree.py: a bench script run from a copy of the tree measures that copy's code, or stops
naming both places where an import finder (an editable install of another checkout) sends
``import tether`` elsewhere."""
from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]

# a Python whose own environment holds no install of the package: the standard finders alone
OWN_ENVIRONMENT = """
import importlib.machinery, sys
sys.meta_path[:] = [f for f in sys.meta_path if f in (importlib.machinery.BuiltinImporter,
                    importlib.machinery.FrozenImporter, importlib.machinery.PathFinder)]
"""

# ... and with another checkout's editable install, whose finder sends ``import tether`` there
ELSEWHERE = """
class Elsewhere:
    def find_spec(self, name, path=None, target=None):
        if name == "tether":
            return importlib.machinery.PathFinder.find_spec(name, [{elsewhere!r}])
        return None
sys.meta_path.insert(0, Elsewhere())
"""


def _copy_of_the_tree(root: Path) -> Path:
    (root / "bench").mkdir(parents=True)
    shutil.copy(REPO / "bench" / "this_tree.py", root / "bench")
    (root / "python" / "tether").mkdir(parents=True)
    (root / "python" / "tether" / "__init__.py").write_text("")
    return root


def _use(copy: Path, redirected: bool) -> subprocess.CompletedProcess:
    prelude = OWN_ENVIRONMENT + (ELSEWHERE.format(elsewhere=str(REPO / "python")) if redirected else "")
    code = (prelude + f"import sys; sys.path.insert(0, {str(copy / 'bench')!r}); "
            "import this_tree; print(this_tree.use())")
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)


def test_a_script_run_from_a_copy_of_the_tree_imports_the_copy(tmp_path):
    copy = _copy_of_the_tree(tmp_path / "copy")
    run = _use(copy, redirected=False)
    assert run.returncode == 0, run.stderr
    assert Path(run.stdout.strip()) == copy.resolve()


def test_a_finder_that_sends_tether_to_another_checkout_stops_the_script_naming_both(tmp_path):
    copy = _copy_of_the_tree(tmp_path / "copy")
    run = _use(copy, redirected=True)
    assert run.returncode == 1, (run.returncode, run.stdout, run.stderr)
    assert str((REPO / "python" / "tether").resolve()) in run.stderr, run.stderr
    assert str((copy / "python" / "tether").resolve()) in run.stderr, run.stderr
    assert run.stdout == ""
