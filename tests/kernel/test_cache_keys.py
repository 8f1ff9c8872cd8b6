"""A model's cache keys do not depend on where the repository is (kernel.built.code_identity):
the identity of the function that builds a model held its file's path, so the same checkout
in another folder derived every kernel again (two clones of one commit had different keys)."""

from nmkane_core.kernel.built import code_identity

SOURCE = """
def model(k=1.0):
    def inner(x):
        return k * x
    return inner(2.0)
"""


def _function(path: str, source: str = SOURCE):
    scope: dict = {}
    exec(compile(source, path, "exec"), scope)
    return scope["model"]


def test_the_same_function_in_two_folders_has_one_identity():
    a = _function("/home/a/nmkane/nmkane_core/systems/m.py")
    b = _function("/tmp/clone/nmkane_core/systems/m.py")
    assert a.__code__.co_filename != b.__code__.co_filename
    assert code_identity(a.__code__) == code_identity(b.__code__)


def test_another_body_has_another_identity():
    a = _function("/x/m.py")
    b = _function("/x/m.py", SOURCE.replace("k * x", "k + x"))  # in the nested function
    assert code_identity(a.__code__) != code_identity(b.__code__)


def test_a_plugged_in_system_copied_to_another_folder_keeps_its_key(tmp_path):
    """End to end: the tutorial's system file in two folders, each loaded in a fresh process."""
    import shutil
    import subprocess
    import sys
    from pathlib import Path

    example = Path(__file__).resolve().parents[2] / "examples" / "isokinetic_bowl.py"
    probe = (
        "import sys\nfrom nmkane_core.run.plugins import load_systems\nfrom nmkane_core import get_system\n"
        "from nmkane_core.kernel.built import built\n"
        "assert load_systems([sys.argv[1]]) == []\n"
        "print(built(get_system('isokinetic-bowl')).key())"
    )
    keys = []
    for folder in ("a", "b/deeper"):
        copy = tmp_path / folder / "bowl.py"
        copy.parent.mkdir(parents=True)
        shutil.copy(example, copy)
        out = subprocess.run([sys.executable, "-c", probe, str(copy)], capture_output=True, text=True, check=True)
        keys.append(out.stdout.strip())
    assert keys[0] and keys[0] == keys[1]
