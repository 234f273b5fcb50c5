#!/usr/bin/python3
"""The house rules a reviewer would otherwise count by hand (docs/conventions.md):
no product source file in daemon/ over 800 lines, no function there over 150 lines, and no
validation scene (gen-NN-NN) or benchmark run letter cited in product code or user docs.

Usage: tools/house_check.py [SOURCE_DIR]    exit 1 and one line per breach when any.
Functions are found by their braces: a top-level '{' opens a body, the matching '}' closes it;
string and character literals and comments are skipped so that braces inside them do not count."""
import os
import re
import sys

# The shared ending sits beside this script, found from its own folder whatever the working
# directory or the interpreter's path settings.
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from house_report import report  # noqa: E402

MAX_FILE_LINES = 800
MAX_FUNCTION_LINES = 150
PRODUCT_DIRS = ("daemon", "proc", "drivers", "tools", "etc", "systemd")
USER_DOCS = ("README.md", "docs")
SCENE_CITE = re.compile(r"\bgen-\d+-\d+\b")
RUN_CITE = re.compile(r"\b[Rr]un [A-Z]\d?\b(?![a-z])")


def strip_code(text):
    """The text with comments and literals blanked (newlines kept), so braces are code's."""
    out, i, n = [], 0, len(text)
    while i < n:
        c = text[i]
        if text.startswith("/*", i):
            j = text.find("*/", i + 2)
            j = n if j < 0 else j + 2
            out.append(re.sub(r"[^\n]", " ", text[i:j]))
            i = j
        elif text.startswith("//", i):
            j = text.find("\n", i)
            j = n if j < 0 else j
            out.append(" " * (j - i))
            i = j
        elif c in "\"'":
            j = i + 1
            while j < n and text[j] != c:
                j += 2 if text[j] == "\\" else 1
            out.append(c + re.sub(r"[^\n]", " ", text[i + 1:j]) + c)
            i = j + 1
        else:
            out.append(c)
            i += 1
    return "".join(out)


def functions(text):
    """(name, first line, line count) of every top-level brace block that follows a ')'."""
    code = strip_code(text)
    depth, start, found = 0, None, []
    for m in re.finditer(r"[{}]", code):
        if m.group() == "{":
            if depth == 0:
                head = code[:m.start()].rstrip()
                start = m.start() if head.endswith(")") else None
                name = re.findall(r"(\w+)\s*\([^()]*(?:\([^()]*\)[^()]*)*\)\s*$", head)
                start_name = name[-1] if name else "?"
            depth += 1
        else:
            depth -= 1
            if depth == 0 and start is not None:
                first = code.count("\n", 0, start) + 1
                last = code.count("\n", 0, m.start()) + 1
                found.append((start_name, first, last - first + 1))
                start = None
    return found


def main():
    root = sys.argv[1] if len(sys.argv) > 1 else os.path.join(os.path.dirname(__file__), "..")
    breaches = []
    for dirpath, _, names in os.walk(os.path.join(root, "daemon")):
        for name in sorted(names):
            if not name.endswith((".c", ".h", ".cpp")):
                continue
            path = os.path.join(dirpath, name)
            rel = os.path.relpath(path, root)
            text = open(path, encoding="utf-8").read()
            lines = text.count("\n")
            if lines > MAX_FILE_LINES:
                breaches.append(f"{rel}: {lines} lines (at most {MAX_FILE_LINES})")
            for fn, first, count in functions(text):
                if count > MAX_FUNCTION_LINES:
                    breaches.append(f"{rel}:{first}: {fn}() is {count} lines (at most {MAX_FUNCTION_LINES})")
    cited = []
    for top in PRODUCT_DIRS + USER_DOCS:
        base = os.path.join(root, top)
        walk = [(os.path.dirname(base), [], [os.path.basename(base)])] if os.path.isfile(base) else os.walk(base)
        for dirpath, dirnames, names in walk:
            dirnames[:] = [d for d in dirnames if d != "records"]
            for name in names:
                path = os.path.join(dirpath, name)
                if name.endswith((".png", ".tiff", ".h5", ".pyc")) or "/accuracy/validation/" in path:
                    continue
                try:
                    text = open(path, encoding="utf-8").read()
                except (UnicodeDecodeError, OSError):
                    continue
                for no, line in enumerate(text.splitlines(), 1):
                    for rx, what in ((SCENE_CITE, "a validation scene"), (RUN_CITE, "a benchmark run")):
                        m = rx.search(line)
                        if m:
                            cited.append(f"{os.path.relpath(path, root)}:{no}: cites {what} ({m.group()})")
    breaches += cited
    return report(breaches, f"house_check: {len(breaches)} breaches")


if __name__ == "__main__":
    sys.exit(main())
