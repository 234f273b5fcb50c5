"""A descatterd process for the HTTP tests (test_http.py, test_live_view.py, the stall
benchmark): its own folder, socket and configuration, ready once `status` says so, the live
view's address read from `status`."""
import json
import os
import subprocess
import time


def merge_groups(text):
    """The configuration with a group given twice merged into its first copy (descatterd
    refuses a repeated group): the base's [camera] and a test's own [camera] lines together,
    every line kept verbatim, groups in order of first appearance."""
    head, order, bodies, current = [], [], {}, None
    for line in text.splitlines():
        stripped = line.strip()
        if stripped.startswith("[") and "]" in stripped:
            name = stripped[1:stripped.index("]")]
            if name not in bodies:
                bodies[name] = []
                order.append(name)
            current = bodies[name]
            continue
        (head if current is None else current).append(line)
    out = head + [line for name in order for line in [f"[{name}]"] + bodies[name]]
    return "\n".join(out) + "\n"


class LiveDaemon:
    def __init__(self, daemon, ctl, tmp, extra_conf="", args=(), wait=True, env=None, preexec_fn=None):
        self.ctl_path, self.tmp = ctl, tmp
        self.sock = os.path.join(tmp, "d.sock")
        self.conf = os.path.join(tmp, "d.conf")
        with open(self.conf, "w") as f:
            f.write(merge_groups("[camera]\nbackend=sim\n[illuminator]\nbackend=sim\n" + extra_conf))
        self.log_path = os.path.join(tmp, "d.log")
        self.log = open(self.log_path, "a")
        self.proc = subprocess.Popen([daemon, "--config", self.conf, "--socket", self.sock, "--no-socket-activation",
                                      *args], stdout=self.log, stderr=self.log, env=env, preexec_fn=preexec_fn)
        self.url = None
        if wait:
            self.wait_ready()

    def wait_ready(self, timeout=120):
        deadline = time.time() + timeout
        while True:
            r = self.ctl("status", "--json", check=False)
            if r.returncode == 0:
                st = json.loads(r.stdout)
                if st["ready"]:
                    self.url = st.get("http", {}).get("url")
                    return st
            if self.proc.poll() is not None:
                raise AssertionError("descatterd exited: " + open(self.log_path).read()[-2000:])
            if time.time() > deadline:
                raise AssertionError("descatterd not ready")
            time.sleep(0.2)

    def ctl(self, *args, check=True, timeout=120):
        return subprocess.run([self.ctl_path, "--address", self.sock, *args], capture_output=True, text=True,
                              check=check, timeout=timeout)

    def page_url(self):
        """The page's address with its token, as a user gets it (`descatterctl live-url`)."""
        return self.ctl("live-url").stdout.strip()

    def status(self):
        return json.loads(self.ctl("status", "--json").stdout)

    def wait_for(self, pred, what, timeout=120):
        deadline = time.time() + timeout
        while True:
            st = self.status()
            if pred(st):
                return st
            if time.time() > deadline:
                raise AssertionError(f"timed out waiting for {what}")
            time.sleep(0.1)

    def stop(self):
        if self.proc.poll() is None:
            self.proc.terminate()
            code = self.proc.wait(60)
            assert code == 0, f"descatterd exited with {code}: " + open(self.log_path).read()[-2000:]
        self.log.close()
