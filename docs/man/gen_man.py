#!/usr/bin/python3
"""Fills a man page template (docs/man/*.scd.in, scdoc markup) from the one source of what it
lists, so that a page cannot drift from the program:

  @OPTIONS program args...@   the options the built program prints for `program args...`
                              (GOption's --help, or descatterctl's own usage): each becomes
                              a scdoc definition; `program` is looked up in --bindir
  @COMMANDS program@          every command `program --help` lists under "commands:", each
                              with the summary and the options of `program COMMAND --help`
  @CONF_KEYS@                 every group and key of the documented configuration
                              (etc/descatterd.conf: the comment block above a key is its text)

  @NAME@ inside a line        the value of --define NAME=VALUE (installed paths)

Usage: gen_man.py TEMPLATE OUT --bindir DIR [--conf FILE] [--define NAME=VALUE ...]
Fails, naming the line, when a template asks for something it cannot produce: a page is never
written with a hole in it."""
import argparse
import os
import re
import subprocess
import sys

# "  -n, --phases=N          text", "  --quick   text", "  -a, --address ADDR   text"
OPTION = re.compile(r"^\s{2,}(?:(-\w), )?(--[\w-]+)(?:[= ](\S+))?(?:\s{2,}(.*))?$")


def scdoc_escape(text):
    # scdoc formats *bold* and _underline_; keep the programs' text literal.
    return text.replace("\\", "\\\\").replace("*", "\\*").replace("_", "\\_")


def parse_help(text):
    """(section title, [(short, long, arg, description)]) for each option group."""
    groups, title, options, last = [], None, None, None
    for line in text.splitlines():
        if not line.strip():
            last = None
            continue
        if not line.startswith(" "):
            title = line.rstrip(":")
            options = None if title.lower().startswith(("usage", "help options")) else []
            if options is not None:
                groups.append((title, options))
            last = None
            continue
        if options is None:
            continue
        m = OPTION.match(line)
        if m and not (last and line.startswith(" " * 8) and not line.strip().startswith("-")):
            short, long_, arg, desc = m.groups()
            last = [short, long_, arg, desc or ""]
            options.append(last)
        elif last is not None:
            last[3] = (last[3] + " " + line.strip()).strip()  # a wrapped description
    return [(t, o) for t, o in groups if o]


def options_scdoc(groups):
    out = []
    for title, options in groups:
        if len(groups) > 1 and title.lower() not in ("application options", "options"):
            out.append(f"## {scdoc_escape(title.rstrip('.'))}\n")
        for short, long_, arg, desc in options:
            name = f"*{short}*, *{long_}*" if short else f"*{long_}*"
            if arg:
                name += f" _{scdoc_escape(arg)}_"
            out.append(name)
            out.append("\t" + scdoc_escape(desc) + "\n")
    return "\n".join(out)


def run_help(bindir, words, where):
    groups = parse_help(help_text(bindir, words, where))
    if not groups:
        sys.exit(f"{where}: `{' '.join(words)}` printed no options")
    return options_scdoc(groups)


def help_text(bindir, words, where):
    prog = os.path.join(bindir, words[0])
    env = dict(os.environ, LC_ALL="C.UTF-8", COLUMNS="200")
    r = subprocess.run([prog] + words[1:], capture_output=True, text=True, env=env)
    if r.returncode != 0 or not r.stdout.strip():
        sys.exit(f"{where}: `{' '.join(words)}` exited {r.returncode}: {r.stderr.strip()}")
    return r.stdout


def summary_of(text):
    """The paragraph GOption prints between the usage line and the option groups."""
    lines, seen_usage = [], False
    for line in text.splitlines():
        if line.lower().startswith("usage"):
            seen_usage = True
            continue
        if line.lower().startswith("help options"):
            break
        if seen_usage and line and not line.startswith(" "):
            lines.append(line.strip())
    return " ".join(lines)


def commands_scdoc(bindir, program, where):
    listing = help_text(bindir, [program, "--help"], where)
    out, in_commands = [], False
    for line in listing.splitlines():
        if not line.startswith(" "):
            in_commands = line.strip().lower() == "commands:"
            continue
        m = re.match(r"^\s{2}([a-z][\w-]*)\s{2,}(.*)$", line)
        if not in_commands or not m:
            continue
        name, oneline = m.groups()
        text = help_text(bindir, [program, name, "--help"], where)
        out.append(f"## {name}\n")
        out.append(scdoc_escape(summary_of(text) or oneline) + "\n")
        # The page lists the global options once (its GLOBAL OPTIONS section), not per command.
        groups = [g for g in parse_help(text) if not g[0].lower().startswith("global options")]
        if groups:
            out.append(options_scdoc(groups))
    if not out:
        sys.exit(f"{where}: `{program} --help` lists no commands")
    return "\n".join(out)


def conf_scdoc(path):
    """Groups and keys of the documented configuration, with the comments above each key."""
    out, comment, keys = [], [], []
    intro = True

    def flush():
        if keys:
            # "++" ends a line in scdoc: one key per line.
            out.append(" ++\n".join(f"*{k}*=_{scdoc_escape(v)}_" if v else f"*{k}*=" for k, v in keys))
            out.append("\t" + scdoc_escape(" ".join(comment) or "See the example file.") + "\n")
        keys.clear()

    for raw in open(path, encoding="utf-8"):
        line = raw.rstrip("\n")
        group = re.match(r"^\[([\w-]+)\]$", line)
        key = re.match(r"^#?([a-z][\w-]*)=(.*)$", line)
        if group:
            flush()
            comment.clear()
            intro = False
            out.append(f"## [{group.group(1)}]\n")
        elif key and not intro:
            keys.append((key.group(1), key.group(2)))
        elif line.startswith("#"):
            if keys:
                flush()
                comment.clear()
            if not intro:
                comment.append(line.lstrip("#").strip())
        elif not line.strip():
            flush()
            comment.clear()
    flush()
    if not any(o.startswith("## [") for o in out):
        sys.exit(f"{path}: no [group] found")
    return "\n".join(out)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("template")
    ap.add_argument("out")
    ap.add_argument("--bindir", required=True)
    ap.add_argument("--conf")
    ap.add_argument("--define", action="append", default=[])
    a = ap.parse_args()
    defines = dict(d.split("=", 1) for d in a.define)
    result = []
    for n, line in enumerate(open(a.template, encoding="utf-8"), 1):
        where = f"{a.template}:{n}"
        for k, v in defines.items():
            line = line.replace(f"@{k}@", v)
        m = re.match(r"^@OPTIONS (.+)@$", line.strip())
        if m:
            result.append(run_help(a.bindir, m.group(1).split(), where) + "\n")
        elif re.match(r"^@COMMANDS (\S+)@$", line.strip()):
            result.append(commands_scdoc(a.bindir, line.strip()[10:-1], where) + "\n")
        elif line.strip() == "@CONF_KEYS@":
            if not a.conf:
                sys.exit(f"{where}: @CONF_KEYS@ needs --conf")
            result.append(conf_scdoc(a.conf) + "\n")
        elif re.search(r"@[A-Z_]+@", line):
            sys.exit(f"{where}: unknown placeholder: {line.strip()}")
        else:
            result.append(line)
    tmp = a.out + ".tmp"
    with open(tmp, "w", encoding="utf-8") as f:
        f.writelines(result)
    os.replace(tmp, a.out)


if __name__ == "__main__":
    main()
