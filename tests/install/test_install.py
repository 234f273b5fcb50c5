#!/usr/bin/python3
"""`cmake --install` into a staging folder (DESTDIR), checked against what issue 14 lists:
programs, units (service, socket, per-rig template), sysusers/tmpfiles snippets, udev rule,
sysctl drop-in, the configuration, scenes and operating model under the data dir, docs, five
man pages and the Python package. Then: no installed file names the source or build tree; the
units point at the installed programs and keep one hardening; the installed configuration
passes `descatterd --check`; the man pages render without warnings; the staged Python package
imports with the build's version.
Usage: test_install.py CMAKE BUILD_DIR SOURCE_DIR PREFIX VERSION plain|sanitized
(a sanitized build's binaries carry source locations by design: the path check is for the
plain build, whose binaries are the product)."""
import os
import re
import subprocess
import sys
import tempfile

CMAKE, BUILD, SRC, PREFIX, VERSION, KIND = sys.argv[1:7]
failures = []


def check(cond, what):
    print(("ok   " if cond else "FAIL ") + what, flush=True)
    if not cond:
        failures.append(what)


# Where one rig's daemon differs from another's: its configuration, socket and directories.
# ReadWritePaths: a rig writes its token file into the shared /run/descatterd, which the main
# unit owns as its RuntimeDirectory and a rig does not (stopping one rig must not remove it).
PER_INSTANCE = {"ExecStart", "RuntimeDirectory", "RuntimeDirectoryMode", "RuntimeDirectoryPreserve",
                "StateDirectory", "CacheDirectory", "Environment", "ReadWritePaths"}


def service_lines(path):
    """The [Service] directives of a unit but the per-instance ones, in order."""
    section, out = None, []
    for line in open(path).read().splitlines():
        if line.startswith("["):
            section = line
        elif section == "[Service]" and "=" in line and not line.startswith("#"):
            if line.split("=", 1)[0] not in PER_INSTANCE:
                out.append(line)
    return out


def without_debug_info(path, tmp):
    """The file's bytes, ELF debug sections removed (they name the build tree by design; Debian
    moves them to -dbgsym packages)."""
    data = open(path, "rb").read()
    if not data.startswith(b"\x7fELF"):
        return data
    out = os.path.join(tmp, "stripped")
    subprocess.run(["objcopy", "--strip-debug", path, out], check=True)
    return open(out, "rb").read()


def main():
    with tempfile.TemporaryDirectory() as stage:
        r = subprocess.run([CMAKE, "--install", BUILD], env=dict(os.environ, DESTDIR=stage),
                           capture_output=True, text=True)
        check(r.returncode == 0, f"cmake --install: {r.stderr.strip()[-400:]}")
        root = stage + PREFIX
        etc = stage + ("/etc" if PREFIX == "/usr" else PREFIX + "/etc")
        lib_root = stage + ("" if PREFIX == "/usr" else PREFIX)
        files = {os.path.relpath(os.path.join(d, f), stage) for d, _, fs in os.walk(stage) for f in fs}

        def has(path, what):
            check(os.path.isfile(path), f"{what}: {os.path.relpath(path, stage)}")

        for p in ("bin/descatterctl", "bin/descatter-sim", "bin/descatter-labsim", "sbin/descatterd"):
            has(os.path.join(root, p), "program")
            check(os.access(os.path.join(root, p), os.X_OK), f"{p} is executable")
        units = os.path.join(lib_root, "lib/systemd/system")
        for u in ("descatterd.service", "descatterd.socket", "descatterd@.service", "descatterd@.socket"):
            has(os.path.join(units, u), "unit")
        has(os.path.join(root, "lib/sysusers.d/descatterd.conf"), "sysusers.d")
        has(os.path.join(root, "lib/tmpfiles.d/descatterd.conf"), "tmpfiles.d")
        has(os.path.join(root, "lib/sysctl.d/60-descatter-gige.conf"), "sysctl.d")
        has(os.path.join(lib_root, "lib/udev/rules.d/60-descatter-gpio.rules"), "udev rule")
        conf = os.path.join(etc, "descatterd/descatterd.conf")
        has(conf, "configuration")
        has(os.path.join(root, "share/descatter/operating-model.conf"), "operating model")
        has(os.path.join(root, "share/descatter/plot_study.py"), "the study's figure helper (descatterctl study)")
        scenes = sorted(f for f in os.listdir(os.path.join(SRC, "etc/scenes")) if f.endswith(".scene"))
        staged_scenes = sorted(os.listdir(os.path.join(root, "share/descatter/scenes")))
        check(scenes == staged_scenes, f"every example scene is installed ({len(scenes)})")
        for page in ("man8/descatterd.8", "man1/descatterctl.1", "man1/descatter-sim.1", "man1/descatter-labsim.1",
                     "man5/descatterd.conf.5"):
            path = os.path.join(root, "share/man", page)
            has(path, "man page")
            r = subprocess.run(["groff", "-man", "-ww", "-z", path], capture_output=True, text=True)
            check(r.returncode == 0 and not r.stderr.strip(), f"{page} renders without warnings {r.stderr.strip()[:200]}")
        docdir = os.path.join(root, "share/doc/descatter")
        for doc in ("README.md", "protocol.md", "operations.md", "python.md", "examples/descatterd.conf"):
            has(os.path.join(docdir, doc), "doc")
        py = [f for f in files if f.endswith("descatter/__init__.py")]
        check(len(py) == 1, f"the Python package: {py}")
        if py:
            has(os.path.join(stage, os.path.dirname(py[0]), "py.typed"), "the package's typing marker (PEP 561)")

        # Nothing installed names the trees it was built from.
        leaks = []
        scratch = tempfile.mkdtemp(dir=stage)
        for f in sorted(files) if KIND == "plain" else []:
            data = without_debug_info(os.path.join(stage, f), scratch)
            for tree in {os.path.realpath(SRC), os.path.realpath(BUILD), SRC, BUILD}:
                if tree.encode() + b"/" in data:
                    leaks.append(f"{f} names {tree}")
        if KIND == "plain":
            check(not leaks, f"no installed file names the source or build tree {leaks[:5]}")
        else:
            print("skip a sanitized build's binaries name their sources (ASan's reports)")

        # Units: the installed programs, one hardening for the main unit and the rig template.
        for u in ("descatterd.service", "descatterd@.service"):
            text = open(os.path.join(units, u)).read()
            exec_start = re.search(r"^ExecStart=(\S+)", text, re.M).group(1)
            check(exec_start == os.path.join(PREFIX, "sbin/descatterd") and "@" not in exec_start,
                  f"{u}: ExecStart={exec_start}")
            check(not re.search(r"@[A-Z_]+@", text), f"{u}: every placeholder configured")
        check(service_lines(os.path.join(units, "descatterd.service")) ==
              service_lines(os.path.join(units, "descatterd@.service")),
              "descatterd@.service has descatterd.service's [Service] settings, but the per-rig ones")
        for u in ("descatterd.service", "descatterd.socket", "descatterd@rig1.service", "descatterd@rig1.socket"):
            path = os.path.join(units, u)
            if "@" in u:  # an instance of the template, as systemctl would name it
                os.symlink(os.path.join(units, u.replace("rig1", "")), path)
            r = subprocess.run(["systemd-analyze", "verify", "--man=no", path], capture_output=True, text=True)
            # The staged programs are not at their installed path yet: that line is expected.
            other = [line for line in r.stderr.splitlines()
                     if not re.search(r"Command \S+ is not executable: No such file", line)]
            check(not other, f"systemd-analyze verify {u}: {other}")
            if "@" in u:
                os.unlink(path)

        # The installed configuration passes the daemon's own check; the programs know the build.
        env = dict(os.environ, DESCATTER_DATA_DIR=os.path.join(root, "share/descatter"))
        r = subprocess.run([os.path.join(root, "sbin/descatterd"), "--check", "--config", conf],
                           capture_output=True, text=True, env=env)
        check(r.returncode == 0, f"descatterd --check on the installed configuration: {r.stderr.strip()}")
        for p in ("bin/descatterctl", "bin/descatter-sim", "bin/descatter-labsim", "sbin/descatterd"):
            out = subprocess.run([os.path.join(root, p), "--version"], capture_output=True, text=True).stdout
            check(out.split()[1:2] == [VERSION], f"{p} --version: {out.strip()}")
        pydir = os.path.dirname(os.path.dirname(os.path.join(stage, py[0]))) if py else stage
        r = subprocess.run([sys.executable, "-c", "import descatter, descatter.aio; print(descatter.__version__)"],
                           capture_output=True, text=True, env=dict(os.environ, PYTHONPATH=pydir), cwd=stage)
        check(r.stdout.strip() == VERSION, f"the staged package imports: {r.stdout.strip()} {r.stderr.strip()[-200:]}")
    print(f"{len(failures)} failed" if failures else "install: ok")
    sys.exit(1 if failures else 0)


if __name__ == "__main__":
    main()
