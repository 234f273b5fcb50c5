#!/usr/bin/python3
"""The spool on a full disk, end to end: a real descatterd on the simulated lab records a
continuous run (tiff + hdf5-run + the raw phases) to a small tmpfs of its own; the test fills
that filesystem mid-run, frees it again and lets the run go on, then stops the daemon with
SIGTERM. Checked with readers that share no code with the writer (h5py, tifffile, Pillow):

  - while the daemon writes, another process holding the growing file open with
    h5py swmr=True sees sets appear;
  - the daemon exits 0 on SIGTERM after the failures (no crash in HDF5's teardown);
  - every entry of the run file is all of one set: its metadata names its set id, and its
    transmissive, scattered and mask planes and raw frames equal that set's own TIFFs, PNG and
    phase folder; sets the disk refused are listed in entry/sets/missing_set_id with a reason,
    and the run went on after the disk had room again;
  - the per-set files stay all-or-nothing: every set with a sidecar has all its files;
  - after kill -9 in the middle of a run, h5py opens the .partial file (swmr=True, no h5clear)
    and its entries equal the sets' own files;
  - the same when the failure is inside HDF5's own writes (an LD_PRELOAD fault layer fails every
    write to the run file with ENOSPC, which a filled disk cannot do: the writer checks the room
    first): the run recovers when writes work again, and a SIGTERM while they still fail exits 0
    and leaves a .partial file h5py opens, each entry all of one set.

The private filesystem needs a mount namespace: the script runs itself under `unshare -m` and
mounts a tmpfs there (root, or a user namespace that allows it); where neither works it is
skipped (exit 77) with the reason.
Usage: test_full_disk.py DESCATTERD DESCATTERCTL SCENE ENOSPC_PRELOAD disk|hdf5
(disk: the filled tmpfs and kill -9; hdf5: the fault layer)"""
import errno
import json
import os
import shutil
import subprocess
import sys
import tempfile

SKIP = 77
NS_MARK = "DS_FULL_DISK_NAMESPACE"


def enter_namespace():
    """Re-runs this script in a private mount namespace (so the tmpfs is nobody else's)."""
    if os.environ.get(NS_MARK):
        return
    env = dict(os.environ, **{NS_MARK: "1"})
    for cmd in (["unshare", "-m"], ["unshare", "-m", "-r"]):
        try:
            r = subprocess.run([*cmd, "true"], capture_output=True)
        except FileNotFoundError:
            break
        if r.returncode == 0:
            os.execvpe(cmd[0], [*cmd, sys.executable, *sys.argv], env)
    print("SKIP: no private mount namespace here (unshare -m refused): cannot make a small filesystem")
    sys.exit(SKIP)


import h5py  # noqa: E402  (after the namespace check: the skip must not depend on them)
import numpy as np  # noqa: E402
import tifffile  # noqa: E402
from PIL import Image  # noqa: E402

from test_daemon_files import Daemon, stems, wait_for  # noqa: E402

# A reader in another process: opens the growing file once with SWMR and prints the number of
# complete sets each time it grows, until it has seen `want` growths.
SWMR_READER = r"""
import sys, time, h5py
path, want = sys.argv[1], int(sys.argv[2])
with h5py.File(path, "r", swmr=True) as f:
    ids = f["entry/sets/set_id"]
    seen, last, deadline = 0, -1, time.time() + 120
    while seen < want and time.time() < deadline:
        ids.refresh()
        n = ids.shape[0]
        if n != last:
            f["entry/transmissive/data"].refresh()
            assert f["entry/transmissive/data"].shape[0] >= n
            print(n, flush=True)
            seen, last = seen + (last >= 0), n
        time.sleep(0.05)
"""


def mount_tmpfs(where, size):
    os.makedirs(where, exist_ok=True)
    r = subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", where], capture_output=True, text=True)
    if r.returncode != 0:
        print(f"SKIP: cannot mount a tmpfs in the private namespace: {r.stderr.strip()}")
        sys.exit(SKIP)


def fill(path):
    """Writes until the filesystem refuses (ENOSPC)."""
    block = b"\0" * (256 * 1024)
    with open(path, "wb", buffering=0) as f:
        try:
            while True:
                f.write(block)
        except OSError as e:
            assert e.errno == errno.ENOSPC, e
    with open(path, "ab", buffering=0) as f:  # the last, smaller, pieces
        try:
            while True:
                f.write(b"\0" * 4096)
        except OSError as e:
            assert e.errno == errno.ENOSPC, e


def spool_stats(d):
    return d.status()["spool"]


def tiff(path):
    return tifffile.imread(path)


def run_entries(f):
    """[(k, set_id, meta)] of the complete sets, read the way docs/operations.md says."""
    e = f["entry"]
    ids = e["sets/set_id"][()]
    n = len(ids)
    ends = e["sets/metadata_end"][:n]
    blob = bytes(e["sets/metadata"][: ends[-1]]) if n else b""
    out, start = [], 0
    for k in range(n):
        out.append((k, int(ids[k]), json.loads(blob[start:ends[k]].decode())))
        start = ends[k]
    return out


def check_entries(f, spool):
    """Every entry equals its own set's files; returns (entry ids, ids checked against files)."""
    e = f["entry"]
    entries = run_entries(f)
    n = len(entries)
    frames_end = e["sets/frames_end"][:n]
    set_index = e["phases/set_index"][: frames_end[-1]] if n else []
    all_stems = {s.rsplit("-", 1)[1]: s for s in stems(spool)}
    checked = []
    for k, set_id, meta in entries:
        assert meta["set_id"] == set_id, (k, set_id, meta["set_id"])
        stem = all_stems.get(f"{set_id:06d}")
        if stem is None:
            continue  # its own files were refused (the disk) or removed: nothing to compare with
        side = json.load(open(os.path.join(spool, stem + ".json")))
        assert side["time_utc"] == meta["time_utc"], (set_id, side["time_utc"], meta["time_utc"])
        np.testing.assert_array_equal(e["transmissive/data"][k], tiff(os.path.join(spool, stem + "-transmissive.tiff")))
        np.testing.assert_array_equal(e["scattered/data"][k], tiff(os.path.join(spool, stem + "-scattered.tiff")))
        np.testing.assert_array_equal(e["mask/data"][k], np.array(Image.open(os.path.join(spool, stem + "-mask.png"))))
        first = frames_end[k - 1] if k else 0
        rows = range(first, frames_end[k])
        assert all(set_index[i] == k for i in rows), (k, list(set_index[first:frames_end[k]]))
        fj = json.load(open(os.path.join(spool, stem + "-phases", "frames.json")))
        assert len(rows) == len(fj["frames"]), (set_id, len(rows), len(fj["frames"]))
        for i, fr in zip(rows, fj["frames"]):
            assert int(e["phases/frame_id"][i]) == fr["frame_id"]
            png = np.array(Image.open(os.path.join(spool, stem + "-phases", fr["file"])))
            np.testing.assert_array_equal(e["phases/data"][i], png)
        checked.append(set_id)
    return [s for _, s, _ in entries], checked


def check_whole_sets(spool, killed=False):
    """All-or-nothing: a set with a sidecar has every file its sidecar lists; no temporaries. After
    kill -9 the hidden temporaries of the writes it interrupted (and the run's reserve) may stay:
    the next start removes them, which kill_mid_run checks."""
    for stem in stems(spool):
        side = json.load(open(os.path.join(spool, stem + ".json")))
        for name in side["files"]:
            assert os.path.exists(os.path.join(spool, name)), (stem, name)
    hidden = [n for n in os.listdir(spool) if n.startswith(".") and not (killed and ".tmp" in n)]
    assert not hidden, hidden


def swmr_reader(path, want):
    return subprocess.Popen([sys.executable, "-c", SWMR_READER, path, str(want)], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)


def full_disk_run(daemon, ctl, scene, tmp, spool):
    d = Daemon(daemon, ctl, tmp, conf_text(spool, scene, 5))
    try:
        d.ctl("start", "--phases", "4")
        wait_for(lambda: spool_stats(d)["sets_written"] >= 2 and spool_stats(d)["run_open"], "first sets")
        (partial,) = [n for n in os.listdir(spool) if n.endswith(".h5.partial")]
        reader = swmr_reader(os.path.join(spool, partial), 3)
        out, err = reader.communicate(timeout=180)
        assert reader.returncode == 0, err
        counts = [int(x) for x in out.split()]
        assert len(counts) >= 4 and counts == sorted(counts) and counts[-1] > counts[0], counts
        print(f"a SWMR reader in another process saw the complete sets grow: {counts}")

        errors = spool_stats(d)["errors"]
        filler = os.path.join(os.path.dirname(spool), "filler")
        fill(filler)
        wait_for(lambda: spool_stats(d)["errors"] >= errors + 2, "sets refused by the full disk")
        os.unlink(filler)
        written = spool_stats(d)["sets_written"]
        wait_for(lambda: spool_stats(d)["sets_written"] >= written + 2, "sets written after space returned")
        d.ctl("stop")
        wait_for(lambda: not d.status()["continuous"], "stop")
        wait_for(lambda: (lambda s: s["pending"] == 0 and not s["run_open"])(spool_stats(d)), "run closed")
        last_error = spool_stats(d)["last_error"]
    finally:
        if d.proc.poll() is None:
            d.proc.terminate()
    rc = d.proc.wait(60)
    assert rc == 0, f"descatterd exited {rc} after SIGTERM (log: {os.path.join(tmp, 'd.log')})"
    print(f"SIGTERM after the disk was full: descatterd exited 0 (last spool error: {last_error})")

    runs = [n for n in os.listdir(spool) if n.startswith("run-") and n.endswith(".h5")]
    assert len(runs) == 1, os.listdir(spool)
    check_whole_sets(spool)
    with h5py.File(os.path.join(spool, runs[0]), "r") as f:
        ids, checked = check_entries(f, spool)
        missing = [int(x) for x in f["entry/sets/missing_set_id"][()]]
        reasons = [bytes(x).rstrip(b"\0").decode() for x in f["entry/sets/missing_reason"][()]]
        n = len(ids)
        # The closed file holds exactly its complete sets: no rolled-back rows remain.
        for name in ("transmissive/data", "scattered/data", "mask/data", "sets/time_utc", "phases/black"):
            assert f["entry/" + name].shape[0] == n, (name, f["entry/" + name].shape, n)
        assert f["entry/phases/data"].shape[0] == f["entry/sets/frames_end"][-1]
    assert missing, "the full disk cost no set of the run file?"
    assert all(r for r in reasons), reasons
    assert not set(missing) & set(ids), set(missing) & set(ids)
    assert ids == sorted(ids), ids
    assert ids[-1] > max(missing), ("nothing appended after space returned", ids, missing)
    # Every set the spool recorded whole is in the run file or listed as missing from it.
    for stem in stems(spool):
        set_id = int(stem.rsplit("-", 1)[1])
        if ids[0] <= set_id <= ids[-1]:
            assert set_id in ids or set_id in missing, (set_id, ids, missing)
    assert len(checked) >= 3, checked
    print(f"run file: {n} sets, each equal to its own files ({len(checked)} compared), "
          f"{len(missing)} missing with reasons, e.g. {reasons[0]!r}")


def kill_mid_run(daemon, ctl, scene, tmp, spool):
    d = Daemon(daemon, ctl, tmp, conf_text(spool, scene, 6))
    d.ctl("start", "--phases", "4")
    written = spool_stats(d)["sets_written"]
    wait_for(lambda: spool_stats(d)["sets_written"] >= written + 2, "sets of the run")
    d.kill()
    (partial,) = [n for n in os.listdir(spool) if n.endswith(".h5.partial")]
    check_whole_sets(spool, killed=True)
    with h5py.File(os.path.join(spool, partial), "r", swmr=True) as f:
        ids, checked = check_entries(f, spool)
    assert ids and checked, (ids, checked)
    # Whatever the kill interrupted: a temporary of a set's file, of its phase folder, the reserve.
    planted = [".set-20000101T000000Z-000999-transmissive.tmp-1-0badf00d.tiff",
               ".set-20000101T000000Z-000999-phases.tmp-1-0badf00d", ".run-20000101T000000Z-000001.reserve.tmp"]
    for name in planted:
        if "phases" in name:
            os.mkdir(os.path.join(spool, name))
            open(os.path.join(spool, name, "phase-00.png"), "wb").write(b"half")
        else:
            open(os.path.join(spool, name), "wb").write(b"half")
    hidden = sorted(n for n in os.listdir(spool) if n.startswith("."))
    Daemon(daemon, ctl, tmp, conf_text(spool, scene, 6)).stop()
    check_whole_sets(spool)
    assert partial in os.listdir(spool), os.listdir(spool)
    print(f"after kill -9: h5py opens {partial} (swmr=True, no h5clear): {len(ids)} sets, "
          f"{len(checked)} equal to their own files; the next start removed {len(hidden)} temporaries")


def conf_text(spool, scene, seed):
    return (f"[daemon]\nspool-dir={spool}\nspool-formats=tiff,hdf5-run\nspool-save-phases=true\n"
            f"[camera]\nbackend=sim\n[illuminator]\nbackend=sim\n[sim]\nscene={scene}\nseed={seed}\n"
            "[acquisition]\nphases=4\n")


def hdf5_writes_fail(daemon, ctl, scene, tmp, spool, preload):
    flag = os.path.join(tmp, "enospc")
    env = {"LD_PRELOAD": preload, "DS_ENOSPC_FLAG": flag, "DS_ENOSPC_SUFFIX": ".h5.partial",
           # The fault layer comes before the sanitizer's runtime in a sanitized daemon, and HDF5
           # leaks the chunks it could not write (full_disk.lsan.supp says which).
           "ASAN_OPTIONS": ":".join(filter(None, [os.environ.get("ASAN_OPTIONS"), "verify_asan_link_order=0"])),
           "LSAN_OPTIONS": ":".join(filter(None, [os.environ.get("LSAN_OPTIONS"), "suppressions=" + os.path.join(
               os.path.dirname(os.path.abspath(__file__)), "full_disk.lsan.supp")]))}
    saved = dict(os.environ)
    os.environ.update(env)
    try:
        d = Daemon(daemon, ctl, tmp, conf_text(spool, scene, 7))
    finally:
        os.environ.clear()
        os.environ.update(saved)
    try:
        d.ctl("start", "--phases", "4")
        written = spool_stats(d)["sets_written"]
        wait_for(lambda: spool_stats(d)["sets_written"] >= written + 2, "first sets")
        # First only the big writes fail (image chunks; HDF5's metadata still goes to disk, as the
        # writer's reserve allows on a full disk): the run recovers in the same file. Then every
        # write fails, until SIGTERM.
        for still_failing_at_stop in (False, True):
            errors = spool_stats(d)["errors"]
            with open(flag, "w") as f:
                f.write("" if still_failing_at_stop else "16384")
            wait_for(lambda: spool_stats(d)["errors"] >= errors + 2, "sets HDF5 failed to write")
            if still_failing_at_stop:
                break
            os.unlink(flag)
            written = spool_stats(d)["sets_written"]
            wait_for(lambda: spool_stats(d)["sets_written"] >= written + 2, "sets written after the failures")
    finally:
        if d.proc.poll() is None:
            d.proc.terminate()
    rc = d.proc.wait(60)
    assert rc == 0, f"descatterd exited {rc} on SIGTERM while HDF5's writes failed (log: {tmp}/d.log)"
    os.unlink(flag)
    runs = sorted(n for n in os.listdir(spool) if n.startswith("run-"))
    # The file could not be closed at SIGTERM: it stays .partial; later sets went nowhere else.
    assert len(runs) == 1 and runs[0].endswith(".h5.partial"), runs
    partial = runs[0]
    check_whole_sets(spool)
    with h5py.File(os.path.join(spool, partial), "r", swmr=True) as f:
        ids, checked = check_entries(f, spool)
        n = len(ids)
        missing = [int(x) for x in f["entry/sets/missing_set_id"][()]]
    # Lost sets are recorded with the next complete set: those of the first failure are there.
    assert missing and ids[-1] > max(missing) and not set(missing) & set(ids), (ids, missing)
    assert len(checked) >= 4, checked
    print(f"HDF5's writes failing (fault layer): SIGTERM while they failed exited 0; {partial} opens "
          f"(swmr=True) with {n} sets, each equal to its own files ({len(checked)} compared), {len(missing)} missing")


def main():
    enter_namespace()
    daemon, ctl, scene, preload, which = sys.argv[1:6]
    with tempfile.TemporaryDirectory() as tmp:
        fs = os.path.join(tmp, "fs")
        mount_tmpfs(fs, "48m")
        try:
            # Each part on a spool of its own, the one before removed: the same room for each.
            parts = {"disk": (full_disk_run, kill_mid_run), "hdf5": (lambda *a: hdf5_writes_fail(*a, preload),)}
            for i, part in enumerate(parts[which]):
                spool = os.path.join(fs, f"spool{i}")
                try:
                    part(daemon, ctl, scene, tmp, spool)
                except BaseException:
                    log = os.path.join(tmp, "d.log")
                    print("descatterd's log, last lines:\n" + "".join(open(log).readlines()[-30:]))
                    raise
                shutil.rmtree(spool)
        finally:
            subprocess.run(["umount", "-l", fs])


if __name__ == "__main__":
    main()
