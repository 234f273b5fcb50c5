#!/usr/bin/python3
"""Every commit a page of README.md or docs/ (records included) cites is in the history of HEAD:
a figure's commit that a clone does not have cannot be checked out to rerun it. A citation is
a word of 7 to 40 hex digits with a letter and a digit (so numbers do not count); it must name
a commit that is an ancestor of HEAD (or HEAD). A page that must keep a commit main does not
have (a record of a run at a working branch's commit, rewritten or merged later) says so within
the citation's line and the next two: "not in main's history", and names main's commit or merge
that holds the code; a branch never merged is named by its name, not by its commit.

Usage: tools/commit_cites.py [SOURCE_DIR]    exit 1 and one line per stale citation when any;
exit 0 with a note, checking nothing, where SOURCE_DIR is not the top of a complete git
checkout (a source package has no .git; a shallow clone lacks the history)."""
import os
import re
import subprocess
import sys

# The shared ending sits beside this script, found from its own folder whatever the working
# directory or the interpreter's path settings.
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from house_report import report  # noqa: E402

ANNOTATED = "not in main's history"
CITE = re.compile(r"\b(?=[0-9a-f]*[a-f])(?=[0-9a-f]*[0-9])[0-9a-f]{7,40}\b")


def git(root, *args):
    return subprocess.run(["git", "-C", root, *args], capture_output=True, text=True)


def skip_reason(root):
    try:
        top = git(root, "rev-parse", "--show-toplevel")
    except OSError:
        return "git is not installed"
    if top.returncode != 0:
        return "not a git checkout"
    if os.path.realpath(top.stdout.strip()) != os.path.realpath(root):
        return f"{root} is not the top of its git checkout (that is {top.stdout.strip()})"
    if git(root, "rev-parse", "--is-shallow-repository").stdout.strip() != "false":
        return "a shallow clone: the history the citations name is not all here"
    return None


def pages(root):
    yield os.path.join(root, "README.md")
    for dirpath, dirnames, names in os.walk(os.path.join(root, "docs")):
        dirnames.sort()
        for name in sorted(names):
            if name.endswith(".md"):
                yield os.path.join(dirpath, name)


def main():
    root = sys.argv[1] if len(sys.argv) > 1 else os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
    why = skip_reason(root)
    if why:
        print(f"commit_cites: skipped, {why}")
        return 0
    history = git(root, "rev-list", "HEAD").stdout.split()
    cites = []
    for path in pages(root):
        if not os.path.isfile(path):
            continue
        with open(path, encoding="utf-8") as f:
            lines = f.read().splitlines()
        for no, line in enumerate(lines, 1):
            for m in CITE.finditer(line):
                after = " ".join([line[m.end():]] + lines[no:no + 2])
                cites.append((m.group(), os.path.relpath(path, root), no, ANNOTATED in " ".join(after.split())))
    stale = []
    for cite, rel, no, annotated in cites:
        found = [c for c in history if c.startswith(cite)]
        if len(found) != 1 and not annotated:
            what = "no commit in the history of HEAD" if not found else "ambiguous in the history of HEAD"
            stale.append(f"{rel}:{no}: cites {cite}, {what}")
    return report(stale, f"commit_cites: {len(cites)} citations, {len(stale)} stale")


if __name__ == "__main__":
    sys.exit(main())
