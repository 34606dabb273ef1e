#!/usr/bin/env python3
"""Every relative link in the tracked Markdown files, and every
dated `docs/experiments/` file named in the tracked sources and docs, points at
a file that exists. Standard library only; run from anywhere in the repo.

    python3 scripts/check_links.py          # exits 1 and lists what is broken
"""
import pathlib
import re
import subprocess
import sys

LINK = re.compile(r"\]\(([^)\s]+)\)")
EXPERIMENT = re.compile(r"docs/experiments/\d{4}-\d{2}-\d{2}-[A-Za-z0-9_.-]+\.md")
SOURCES = (".md", ".rs", ".py", ".sh", ".toml")


def tracked(root):
    out = subprocess.run(["git", "ls-files"], cwd=root, check=True, capture_output=True, text=True)
    return [root / line for line in out.stdout.splitlines() if line.endswith(SOURCES)]


def broken_links(root, path):
    text = path.read_text(encoding="utf-8", errors="replace")
    for target in LINK.findall(text) if path.suffix == ".md" else []:
        if re.match(r"^[a-z]+:", target) or target.startswith("#"):
            continue
        file = target.split("#", 1)[0]
        if file and not (path.parent / file).exists():
            yield f"{path.relative_to(root)}: link to {target}"
    for named in EXPERIMENT.findall(text):
        if not (root / named).exists():
            yield f"{path.relative_to(root)}: names {named}"


def main(root=None):
    root = root or pathlib.Path(__file__).resolve().parent.parent
    problems = [p for path in tracked(root) if path.exists() for p in broken_links(root, path)]
    for p in problems:
        print(p)
    print(f"{len(problems)} broken link(s)" if problems else "links: every target exists")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
