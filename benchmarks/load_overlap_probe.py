"""Does loading the stored executables overlap with importing the package? A probe of the program
store's prefetch (docrl_jax.train.program_store.prefetch), on a GPU machine:

    python3 -m docrl_jax.train --config td3_lstm --set train.total_env_steps=819200 --compile-cache C --run-dir R
    python3 benchmarks/load_overlap_probe.py extract C/programs RAW      # the executables, without their trees
    python3 benchmarks/load_overlap_probe.py {serial,threads_after,overlap} RAW

Each mode is a fresh process that imports JAX and initialises the GPU, then: `serial` imports the
whole train command and loads the executables one after another; `threads_after` imports it and
loads them in threads (the store before the prefetch); `overlap` starts the threads first and
imports meanwhile (the prefetch). Prints the seconds after the process's start at which each
phase ended, and per executable (start, read, end, bytes).
"""

import glob
import io
import json
import os
import pickle
import sys
import threading
import time

T0 = time.time()
log = {}


def mark(name: str) -> None:
    log[name] = round(time.time() - T0, 3)


def main() -> None:
    import jax
    mark("jax_imported")
    devices = jax.devices()
    mark("devices")
    mode = sys.argv[1]
    if mode == "extract":
        store, raw = sys.argv[2], sys.argv[3]
        os.makedirs(raw, exist_ok=True)
        for path in sorted(glob.glob(store + "/*.bin"), key=os.path.getmtime):
            with open(path, "rb") as f:
                payload = pickle.load(f)[1]
            with open(os.path.join(raw, os.path.basename(path)), "wb") as f:
                f.write(payload)
        return
    from jax.experimental import serialize_executable
    files, results = sorted(glob.glob(sys.argv[2] + "/*.bin")), {}

    def load(path: str) -> None:
        start = time.time() - T0
        with open(path, "rb") as f:
            data = f.read()
        unloaded = serialize_executable._JaxPjrtUnpickler(io.BytesIO(data), devices[0].client, list(devices)).load()[0]
        read = time.time() - T0
        unloaded.load()
        results[os.path.basename(path)[:8]] = (round(start, 3), round(read, 3), round(time.time() - T0, 3), len(data))

    def in_threads() -> list:
        threads = [threading.Thread(target=load, args=(f,)) for f in files]
        for t in threads:
            t.start()
        return threads

    if mode == "overlap":
        threads = in_threads()
        mark("loads_started")
    import docrl_jax.train.run  # noqa: F401  (everything a launch imports: MuJoCo, MJX, Flax, Orbax, ...)
    mark("imports_done")
    if mode == "serial":
        for f in files:
            load(f)
    elif mode == "threads_after":
        threads = in_threads()
    for t in threads if mode != "serial" else []:
        t.join()
    mark("loads_joined")
    print(mode, json.dumps(log), json.dumps(results))


if __name__ == "__main__":
    main()
