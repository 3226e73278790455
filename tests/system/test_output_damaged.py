"""`plot DIR` on damaged or incomplete results directories: one line
naming the damaged file, exit 2, before anything is drawn; no traceback.  Before, a
truncated HDF5 file ended in "figures not drawn: OSError: Unable to open file" (no file
named), a truncated XDMF file in "TypeError: 'NoneType' object is not iterable", a truncated
contact.h5 in VTK aborting the pictures' process ("*** End of error message ***")."""
import shutil

import h5py
import pytest

from conftest import run_cli


def _truncate(name, size):
    def damage(out):
        data = (out / name).read_bytes()
        (out / name).write_bytes(data[:size if size > 0 else len(data) + size])
    return damage


def _write(name, text):
    def damage(out):
        (out / name).write_text(text)
    return damage


def _drop_dataset(out):
    """A dataset solution.xdmf names is missing (a run killed inside an HDF5 write)."""
    with h5py.File(out / "solution.h5", "a") as f:
        del f["Function/u"][sorted(f["Function/u"])[-1]]


DAMAGES = {
    "solution.h5 truncated": ("solution.h5", _truncate("solution.h5", 3000)),
    "contact.h5 truncated": ("contact.h5", _truncate("contact.h5", 2000)),
    "solution.xdmf truncated": ("solution.xdmf", _truncate("solution.xdmf", -200)),
    "contact.xdmf truncated": ("contact.xdmf", _truncate("contact.xdmf", 500)),
    "summary.json truncated": ("summary.json", _truncate("summary.json", 200)),
    "summary.json not an object": ("summary.json", _write("summary.json", "[]\n")),
    "contact.csv truncated": ("contact.csv", _truncate("contact.csv", -40)),
    "a dataset missing": ("solution.h5", _drop_dataset),
}


@pytest.mark.parametrize("damage", DAMAGES, ids=list(DAMAGES))
def test_plot_of_a_damaged_directory_is_one_line_naming_the_file(tiny_run_dir, tmp_path, damage):
    name, apply = DAMAGES[damage]
    out = tmp_path / "r"
    shutil.copytree(tiny_run_dir, out)
    apply(out)
    proc = run_cli(["plot", out, "--animate"])
    lines = [x for x in (proc.stdout + proc.stderr).splitlines() if x.strip()]
    assert proc.returncode == 2, lines
    assert len(lines) == 1 and "Traceback" not in proc.stderr, lines
    assert f"{out / name}:" in lines[0], lines
    assert not list(out.glob("*.png")) and not (out / "animation.gif").exists()


def test_plot_of_a_killed_run_names_what_is_missing(tiny_run_dir, tmp_path):
    """A run killed before its end has no summary.json: refused in one line."""
    out = tmp_path / "r"
    shutil.copytree(tiny_run_dir, out)
    (out / "summary.json").unlink()
    proc = run_cli(["plot", out, "--animate"])
    assert proc.returncode == 2 and "Traceback" not in proc.stderr
    assert proc.stderr.strip().count("\n") == 0 and "summary.json" in proc.stderr
    assert "killed" in proc.stderr
