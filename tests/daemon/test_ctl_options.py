#!/usr/bin/python3
"""descatterctl's short options have one meaning across the program (issue 34): no short letter
names two different long options, counting the global options of `descatterctl --help` and
every command's own (`descatterctl COMMAND --help`, commands as the program lists them); and
every command's --help lists the global options. Read from the built program's help, the text
a user reads, so a new option table cannot slip past.
Usage: test_ctl_options.py DESCATTERCTL"""
import re
import subprocess
import sys

CTL = sys.argv[1]
# "  -n, --phases=N   text", "  -a, --address ADDR   text"
OPTION = re.compile(r"^\s{2,}(-\w), (--[\w-]+)")
LONG = re.compile(r"^\s{2,}(?:-\w, )?(--[\w-]+)")
failures = []


def check(cond, what):
    print(("ok   " if cond else "FAIL ") + what, flush=True)
    if not cond:
        failures.append(what)


def help_text(*words):
    r = subprocess.run([CTL, *words, "--help"], capture_output=True, text=True, env={"LC_ALL": "C.UTF-8"})
    check(r.returncode == 0 and r.stdout.strip(), f"descatterctl {' '.join(words)} --help")
    return r.stdout


def main():
    top = help_text()
    commands, section = [], None
    for line in top.splitlines():
        if line and not line.startswith(" "):
            section = line.strip().rstrip(":")
        m = re.match(r"^  ([a-z][\w-]*)\s{2,}", line)
        if section == "commands" and m:
            commands.append(m.group(1))
    global_longs = [m.group(1) for line in top.splitlines() if (m := LONG.match(line))]
    # What the program lists today; a command dropped from the list would drop out of the check.
    check(len(commands) >= 15 and {"capture", "start", "stop", "separate", "validate"} <= set(commands),
          f"the commands listed: {commands}")
    check({"--address", "--token", "--token-file"} <= set(global_longs), f"the global options: {global_longs}")

    meanings = {}  # short letter -> {long option: [where]}
    for line in top.splitlines():
        if m := OPTION.match(line):
            meanings.setdefault(m.group(1), {}).setdefault(m.group(2), []).append("global")
    for cmd in commands:
        text = help_text(cmd)
        for line in text.splitlines():
            if m := OPTION.match(line):
                meanings.setdefault(m.group(1), {}).setdefault(m.group(2), []).append(cmd)
        longs = {m.group(1) for line in text.splitlines() if (m := LONG.match(line))}
        missing = [g for g in ("--address", "--token", "--token-file") if g not in longs]
        check(not missing and "Global options" in text, f"{cmd} --help lists the global options {missing or ''}")
    # The check has something to check: the acquisition letters are there.
    check({"-a", "-n", "-m", "-e", "-g", "-o", "-q", "-j"} <= set(meanings),
          f"short letters found: {sorted(meanings)}")
    for short, longs in sorted(meanings.items()):
        check(len(longs) == 1, f"{short} means one thing: " +
              "; ".join(f"{lng} in {', '.join(sorted(set(where)))}" for lng, where in sorted(longs.items())))
    print(f"{len(failures)} failed" if failures else "short options: ok")
    sys.exit(1 if failures else 0)


if __name__ == "__main__":
    main()
