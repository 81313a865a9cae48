"""Build hook: bake the commit and dirty state of the source into the installed package.

The results files record which code made them (runner/provenance.py).  Asking
git at run time would describe whatever checkout happens to surround the
installed files, not the code that was installed, so the build writes
``gyrolab/_build_info.py`` into the wheel instead (as REBOUND bakes its git
hash in at build time).  Everything else is in pyproject.toml.
"""

import subprocess
from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py


def git_state(directory):
    """(commit, dirty) of the git work tree at ``directory``; ("unknown", -1) outside git."""
    try:

        def git(*args):
            return subprocess.run(
                ["git", "-C", str(directory), *args], capture_output=True, text=True, timeout=10, check=True
            ).stdout.strip()

        return git("rev-parse", "HEAD"), int(bool(git("status", "--porcelain", "--untracked-files=no")))
    except (OSError, subprocess.SubprocessError):
        return "unknown", -1


class BuildPyWithInfo(build_py):
    def run(self):
        super().run()
        if getattr(self, "editable_mode", False):
            return  # an editable install runs the work tree itself: provenance asks it at run time
        commit, dirty = git_state(Path(__file__).resolve().parent)
        target = Path(self.build_lib) / "gyrolab" / "_build_info.py"
        target.write_text(f'"""Written by setup.py at build time."""\nGIT_COMMIT = {commit!r}\nGIT_DIRTY = {dirty}\n')


setup(cmdclass={"build_py": BuildPyWithInfo})
