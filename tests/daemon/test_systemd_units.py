#!/usr/bin/python3
"""The socket paths of the systemd units, the daemon and the packaging agree, and survive a
restart (issue 10: RuntimeDirectory=descatterd with ListenStream=/run/descatterd/... meant that
restarting the service removed the socket file, and socket activation could not reach the
daemon again until the socket unit was restarted). This machine has no systemd as PID 1, so
the restart itself cannot run here; what can:
  - the path logic of the units, rule by rule (below);
  - systemd-analyze verify on the units as configured by the build;
  - the daemon under socket activation (systemd-socket-activate hands it the listening socket
    as systemd would): it serves on it, and when it stops it leaves the socket file, which is
    systemd's, in place.
Usage: test_systemd_units.py DESCATTERD SOURCE_DIR BUILD_DIR"""
import os
import re
import signal
import socket
import subprocess
import sys
import tempfile
import time

DESCATTERD, SRC, BUILD = sys.argv[1:4]
failures = []


def check(cond, what):
    print(("ok   " if cond else "FAIL ") + what, flush=True)
    if not cond:
        failures.append(what)


def directives(path):
    """{(section, key): [values]} of a unit file."""
    out, section = {}, None
    for line in open(path).read().splitlines():
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        if line.startswith("["):
            section = line.strip("[]")
        elif "=" in line:
            k, v = line.split("=", 1)
            out.setdefault((section, k.strip()), []).append(v.strip())
    return out


def one(d, section, key):
    v = d.get((section, key))
    return v[-1] if v else None


def request(path, line):
    with socket.socket(socket.AF_UNIX) as s:
        s.settimeout(20)
        s.connect(path)
        s.sendall(line.encode() + b"\n")
        buf = b""
        while not buf.endswith(b"\n"):
            chunk = s.recv(65536)
            if not chunk:
                break
            buf += chunk
        return buf.decode()


def main():
    units = os.path.join(BUILD, "systemd")
    service = directives(os.path.join(units, "descatterd.service"))
    template = directives(os.path.join(units, "descatterd@.service"))
    sock = directives(os.path.join(SRC, "systemd/descatterd.socket"))
    tsock = directives(os.path.join(SRC, "systemd/descatterd@.socket"))
    listen = one(sock, "Socket", "ListenStream")

    # 1. A socket inside the service's RuntimeDirectory is only safe if that directory survives
    #    a restart (systemd removes a RuntimeDirectory when the service stops unless preserved).
    rt = one(service, "Service", "RuntimeDirectory")
    inside = rt is not None and listen.startswith(f"/run/{rt}/")
    preserved = one(service, "Service", "RuntimeDirectoryPreserve") in ("yes", "restart")
    check(not inside or preserved,
          f"descatterd.service: ListenStream {listen} inside RuntimeDirectory={rt} needs "
          f"RuntimeDirectoryPreserve=yes (has {one(service, 'Service', 'RuntimeDirectoryPreserve')})")
    # 2. The per-rig template must not own the shared directory at all: stopping one rig would
    #    remove the others' sockets.
    check(one(template, "Service", "RuntimeDirectory") is None,
          "descatterd@.service: no RuntimeDirectory (the rigs share /run/descatterd)")
    # 3. The daemon's default socket (what it binds when started by hand) is the unit's.
    conf = tempfile.NamedTemporaryFile("w", suffix=".conf", delete=False)
    conf.write("[camera]\nbackend=sim\n[illuminator]\nbackend=sim\n")
    conf.close()
    out = subprocess.run([DESCATTERD, "--check", "--config", conf.name], capture_output=True, text=True).stdout
    os.unlink(conf.name)
    default = re.search(r"^socket=(.*)$", out, re.M)
    check(default is not None and default.group(1) == listen,
          f"the daemon's default [daemon] socket {default.group(1) if default else None} is descatterd.socket's {listen}")
    # 4. The template's daemon binds (by hand) where its socket unit listens.
    exec_start = one(template, "Service", "ExecStart")
    m = re.search(r"--socket (\S+)", exec_start or "")
    check(m is not None and m.group(1) == one(tsock, "Socket", "ListenStream"),
          f"descatterd@.service --socket {m.group(1) if m else None} is descatterd@.socket's "
          f"{one(tsock, 'Socket', 'ListenStream')}")
    # 5. Who may connect: the socket's group and mode, the directory's mode as tmpfiles makes it.
    tmpfiles = open(os.path.join(SRC, "systemd/descatterd.tmpfiles")).read()
    run_dir = re.search(r"^d\s+(/run/\S+)\s+(\d+)\s+(\S+)\s+(\S+)", tmpfiles, re.M)
    check(run_dir is not None and os.path.dirname(listen) == run_dir.group(1) and
          one(sock, "Socket", "DirectoryMode") == run_dir.group(2) and
          one(service, "Service", "RuntimeDirectoryMode") == run_dir.group(2),
          f"/run/descatterd: tmpfiles.d {run_dir.groups() if run_dir else None}, socket DirectoryMode "
          f"{one(sock, 'Socket', 'DirectoryMode')}, RuntimeDirectoryMode {one(service, 'Service', 'RuntimeDirectoryMode')}")
    check(one(sock, "Socket", "SocketGroup") == one(service, "Service", "Group"),
          "the socket's group is the service's")
    # 5b. Descriptors: the limit is set on purpose, above what the largest socket and HTTP limits
    #     take (max-clients 1024, max-connections 4096, 256 live pages with two each for their
    #     bridges), so that the daemon does not lower [http] max-connections at start.
    for name, unit in (("descatterd.service", service), ("descatterd@.service", template)):
        nofile = one(unit, "Service", "LimitNOFILE")
        check(nofile is not None and nofile.isdigit() and int(nofile) >= 1024 + 4096 + 2 * 256 + 64,
              f"{name}: LimitNOFILE={nofile} above max-clients + max-connections + bridges + the daemon's own")

    # 6. systemd's own check of the configured units (the program is not installed here: that
    #    one line is expected).
    for u in ("descatterd.service", "descatterd@.service"):
        path = os.path.join(units, u)
        with tempfile.TemporaryDirectory() as tmp:
            # verify wants the socket unit next to the service it requires
            for f in (path, os.path.join(SRC, "systemd", u.replace(".service", ".socket"))):
                os.symlink(f, os.path.join(tmp, os.path.basename(f)))
            target = os.path.join(tmp, u.replace("@", "@rig1") if "@" in u else u)
            if "@" in u:
                os.symlink(path, target)
            r = subprocess.run(["systemd-analyze", "verify", "--man=no", target], capture_output=True, text=True)
        other = [l for l in r.stderr.splitlines() if not re.search(r"Command \S+ is not executable", l)]
        check(not other, f"systemd-analyze verify {os.path.basename(target)}: {other}")

    # 7. Socket activation: the daemon serves on the socket it is handed, and leaves it in place
    #    when it stops (systemd keeps listening on it for the next start).
    with tempfile.TemporaryDirectory() as d:
        path = os.path.join(d, "descatterd.sock")
        act = subprocess.Popen(["systemd-socket-activate", "-l", path, DESCATTERD, "--sim"],
                               stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        try:
            for _ in range(200):
                if os.path.exists(path):
                    break
                time.sleep(0.05)
            reply = request(path, '{"id":1,"cmd":"hello"}')
            check('"ok":true' in reply, f"the activated daemon answers on the socket it was handed: {reply[:80]}")
            act.send_signal(signal.SIGTERM)
            act.wait(timeout=30)
            check(act.returncode == 0, f"it stops cleanly (exit {act.returncode})")
            check(os.path.exists(path), "the socket file, systemd's, is still there after the daemon stopped")
        finally:
            if act.poll() is None:
                act.kill()
                act.wait()

    if failures:
        print(f"{len(failures)} failed", file=sys.stderr)
        sys.exit(1)


main()
