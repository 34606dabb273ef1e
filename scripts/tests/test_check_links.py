"""scripts/check_links.py: broken relative links and missing experiment files are found."""

import contextlib
import io
import os
import pathlib
import subprocess
import sys
import tempfile
import unittest

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))
import check_links  # noqa: E402


# Built here, so that this file does not name a study that does not exist.
STUDY = "docs/experiments/" + "2026-01-01-"


class CheckLinksTest(unittest.TestCase):
    def repo(self, files):
        root = pathlib.Path(tempfile.mkdtemp())
        for name, text in files.items():
            (root / name).parent.mkdir(parents=True, exist_ok=True)
            (root / name).write_text(text)
        subprocess.run(["git", "init", "-q"], cwd=root, check=True)
        subprocess.run(["git", "add", "-A"], cwd=root, check=True)
        return root

    def run_on(self, root):
        out = io.StringIO()
        with contextlib.redirect_stdout(out):
            code = check_links.main(root)
        return code, out.getvalue()

    def test_links_that_resolve_pass(self):
        root = self.repo({
            "README.md": "[a](docs/a.md#part) [web](https://example.org) [top](#title)\n",
            "docs/a.md": f"[back](../README.md) {STUDY}x.md\n",
            STUDY + "x.md": "x\n",
        })
        code, out = self.run_on(root)
        self.assertEqual(code, 0, out)

    def test_a_missing_link_target_and_a_missing_experiment_are_reported(self):
        root = self.repo({
            "README.md": "[gone](docs/gone.md)\n",
            "src/lib.rs": f"// see {STUDY}missing.md\n",
        })
        code, out = self.run_on(root)
        self.assertEqual(code, 1)
        self.assertIn("README.md: link to docs/gone.md", out)
        self.assertIn(f"src/lib.rs: names {STUDY}missing.md", out)
        self.assertIn("2 broken link(s)", out)


if __name__ == "__main__":
    unittest.main()
