#!/usr/bin/python3
"""Where the programs find their data (scenes, the operating model) with no environment
variable (issue 34): run from the build tree, etc/ of the source tree; copied out of the build
tree (as an installed program is, with no marker next to it), the installed data dir;
$DESCATTER_DATA_DIR overrides both. Then end to end: descatterd from the build tree, started
without DESCATTER_DATA_DIR, runs a `--target-error` capture (which needs the operating model).
The expected folders come from the arguments (the source tree ctest was configured from), not
from anything the programs print about themselves.
Usage: test_data_dir.py BINDIR SOURCE_DIR INSTALLED_DATA_DIR"""
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time

BIN, SRC, DATA_DIR = sys.argv[1], sys.argv[2], sys.argv[3]
DAEMON = os.path.join(BIN, "descatterd")
CTL = os.path.join(BIN, "descatterctl")
failures = []


def check(cond, what):
    print(("ok   " if cond else "FAIL ") + what, flush=True)
    if not cond:
        failures.append(what)


# ctest sets DESCATTER_DATA_DIR for every test: this one needs it unset.
CLEAN_ENV = {k: v for k, v in os.environ.items() if k != "DESCATTER_DATA_DIR"}
SOURCE_MODEL = os.path.realpath(os.path.join(SRC, "etc", "operating-model.conf"))


def model_line(daemon, env):
    """The operating model `descatterd --check --sim` reports (its path, or the note why none)."""
    r = subprocess.run([daemon, "--check", "--sim"], capture_output=True, text=True, env=env, timeout=120)
    for line in r.stdout.splitlines():
        if line.startswith("# operating model: "):
            return r.returncode, line[len("# operating model: "):]
        if line.startswith("# automatic operating point off: "):
            return r.returncode, "off: " + line
    return r.returncode, f"no model line: {r.stderr.strip()}"


def lookups(tmp):
    rc, path = model_line(DAEMON, CLEAN_ENV)
    check(rc == 0 and os.path.realpath(path) == SOURCE_MODEL,
          f"build/bin/descatterd without DESCATTER_DATA_DIR reads etc/ of the source tree: {path}")
    # A copy outside build/bin has no marker next to it, as an installed program has none.
    elsewhere = os.path.join(tmp, "bin")
    os.mkdir(elsewhere)
    shutil.copy2(DAEMON, elsewhere)
    rc, path = model_line(os.path.join(elsewhere, "descatterd"), CLEAN_ENV)
    installed = os.path.join(DATA_DIR, "operating-model.conf")
    check(rc == 0 and installed in path and SRC not in path and os.path.realpath(SRC) not in path,
          f"a copy outside the build tree reads the installed data dir {DATA_DIR}: {path}")
    # The variable wins over the build tree's marker.
    data = os.path.join(tmp, "data")
    os.mkdir(data)
    shutil.copy(SOURCE_MODEL, data)
    rc, path = model_line(DAEMON, dict(CLEAN_ENV, DESCATTER_DATA_DIR=data))
    check(rc == 0 and os.path.realpath(path) == os.path.realpath(os.path.join(data, "operating-model.conf")),
          f"DESCATTER_DATA_DIR overrides the build tree's data: {path}")


def automatic_capture(tmp):
    sock = os.path.join(tmp, "d.sock")
    log = open(os.path.join(tmp, "d.log"), "w")
    d = subprocess.Popen([DAEMON, "--sim", "--socket", sock, "--no-socket-activation"], stdout=log,
                         stderr=subprocess.STDOUT, env=CLEAN_ENV)
    try:
        deadline = time.time() + 120
        while True:
            r = subprocess.run([CTL, "-a", sock, "status", "--json"], capture_output=True, text=True, env=CLEAN_ENV)
            if r.returncode == 0 and json.loads(r.stdout)["ready"]:
                break
            assert d.poll() is None, "descatterd exited"
            assert time.time() < deadline, "descatterd not ready"
            time.sleep(0.2)
        om = json.loads(r.stdout).get("operating_model", {})
        check(om.get("loaded") is True and os.path.realpath(om.get("path", "")) == SOURCE_MODEL,
              f"status: the operating model of the source tree is loaded: {om}")
        out = os.path.join(tmp, "auto")
        r = subprocess.run([CTL, "-a", sock, "capture", "-q", "--target-error", "0.1", "--out", out],
                           capture_output=True, text=True, env=CLEAN_ENV, timeout=300)
        metas = [n for n in os.listdir(out) if n.startswith("set-") and n.endswith(".json")] \
            if r.returncode == 0 else []
        op = json.load(open(os.path.join(out, metas[0]))).get("settings", {}).get("operating_point", {}) \
            if metas else {}
        check(r.returncode == 0 and op.get("target_error") == 0.1,
              f"a --target-error capture succeeds without DESCATTER_DATA_DIR: {r.stderr.strip()} {op}")
    finally:
        d.terminate()
        check(d.wait(30) == 0, "descatterd exits cleanly")
        log.close()


def main():
    with tempfile.TemporaryDirectory() as tmp:
        lookups(tmp)
        automatic_capture(tmp)
    print(f"{len(failures)} failed" if failures else "data dir: ok")
    sys.exit(1 if failures else 0)


if __name__ == "__main__":
    main()
