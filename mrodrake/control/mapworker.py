"""Point-world maps built ahead of need in a worker process, so that the map of a mission's next motion is
solved on another core while the current motion is simulated.

A map is a function of its free-space polygon and the map options alone (:func:`~mrodrake.control.tasks.
build_map`).  The worker (``python -m mrodrake.control.mapworker``, one per process that asks, started on the
first request) builds it with the same code as the mission, BLAS single-threaded as in a mission (the
compiled assembly's result does not depend on its thread count), and sends it back pickled, which is exact.
A map taken from the worker is therefore the map the mission would have built itself: a request changes when
a map is ready, never which map a motion gets.  The worker reads length-prefixed pickles on its standard
input and writes its results on its standard output; it ignores Ctrl-C (the parent handles it) and ends when
its input closes, i.e. with the process that started it, or after :data:`IDLE_EXIT` seconds without a request
(a notebook kernel keeps no idle worker and its solve buffers; the next request starts a new one, and a request
that met a worker on its way out fails, so the mission builds that map itself).
"""

from __future__ import annotations

import os
import pickle
import select
import signal
import struct
import subprocess
import sys
import threading
from concurrent.futures import Future

import shapely

from mrodrake.control.pointworld import PointWorldMap

_HEADER = struct.Struct("<Q")
#: Seconds without a request after which a worker ends.
IDLE_EXIT = 120.0


def _send(stream, obj) -> None:
    data = pickle.dumps(obj, protocol=pickle.HIGHEST_PROTOCOL)
    stream.write(_HEADER.pack(len(data)))
    stream.write(data)
    stream.flush()


def _read_exact(stream, size: int) -> bytes:
    """``size`` bytes from ``stream`` (EOFError if it closes first); works on unbuffered streams too."""
    chunks, left = [], size
    while left > 0:
        chunk = stream.read(left)
        if not chunk:
            raise EOFError
        chunks.append(chunk)
        left -= len(chunk)
    return b"".join(chunks)


def _receive(stream):
    """The next pickled object on ``stream`` (EOFError when it has closed)."""
    size = _HEADER.unpack(_read_exact(stream, _HEADER.size))[0]
    return pickle.loads(_read_exact(stream, size))


class MapWorker:
    """A worker process building point-world maps; :meth:`submit` returns a Future of the map."""

    def __init__(self, idle_exit: float = IDLE_EXIT):
        env = dict(os.environ, OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1", MKL_NUM_THREADS="1")
        self._proc = subprocess.Popen([sys.executable, "-m", "mrodrake.control.mapworker", repr(float(idle_exit))],
                                      stdin=subprocess.PIPE, stdout=subprocess.PIPE, env=env, close_fds=True)
        self._pid = os.getpid()
        self._lock, self._send_lock = threading.Lock(), threading.Lock()
        self._pending: dict[int, Future] = {}
        self._next = 0
        self._reader = threading.Thread(target=self._read, name="mrodrake-map-worker", daemon=True)
        self._reader.start()

    @property
    def alive(self) -> bool:
        return self._pid == os.getpid() and self._proc.poll() is None

    def submit(self, polygon, options: dict) -> Future:
        """The map of ``polygon`` (a shapely Polygon) with ``options`` (``PointWorldMap.build`` keywords)."""
        fut: Future = Future()
        with self._lock:
            key, self._next = self._next, self._next + 1
            self._pending[key] = fut
        try:  # outside the lock: the reader must be able to drain results while this write waits for room
            with self._send_lock:
                _send(self._proc.stdin, (key, shapely.to_wkb(polygon), dict(options)))
        except (BrokenPipeError, OSError, ValueError) as exc:
            with self._lock:
                self._pending.pop(key, None)
            if not fut.done():
                fut.set_exception(RuntimeError(f"map worker: {exc}"))
        return fut

    def _read(self) -> None:
        while True:
            try:
                key, ok, value = _receive(self._proc.stdout)
            except (EOFError, OSError, ValueError, pickle.UnpicklingError):
                break
            with self._lock:
                fut = self._pending.pop(key, None)
            if fut is not None and ok:
                fut.set_result(value)
            elif fut is not None:
                fut.set_exception(RuntimeError(value))
        with self._lock:
            pending, self._pending = list(self._pending.values()), {}
        for fut in pending:
            fut.set_exception(RuntimeError("map worker: ended"))

    def detach(self) -> None:
        """Drop the pipes inherited by a forked process (the worker belongs to the parent)."""
        for stream in (self._proc.stdin, self._proc.stdout):
            try:
                os.close(stream.fileno())
            except (OSError, ValueError):
                pass


_WORKER: MapWorker | None = None
_WORKER_LOCK = threading.Lock()


def map_worker() -> MapWorker:
    """This process's map worker (started on first use, again after a fork or if it ended)."""
    global _WORKER
    with _WORKER_LOCK:
        w = _WORKER
        if w is None or not w.alive:
            if w is not None and w._pid != os.getpid():
                w.detach()
            _WORKER = w = MapWorker()
        return w


def _serve(idle_exit: float) -> None:
    """The worker's loop: build every requested map, answer (key, True, map) or (key, False, one-line error);
    end when the input closes or after ``idle_exit`` seconds without a request."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    from threadpoolctl import threadpool_limits

    threadpool_limits(limits=1, user_api="blas")
    stdin, stdout = sys.stdin.buffer.raw, sys.stdout.buffer  # unbuffered input: select sees every byte not read
    sys.stdout = sys.stderr  # nothing but results on the pipe
    while True:
        if not select.select([stdin], [], [], idle_exit)[0]:
            return
        try:
            key, wkb, options = _receive(stdin)
        except EOFError:
            return
        try:
            result = (key, True, PointWorldMap.build(shapely.from_wkb(wkb), **options))
        except Exception as exc:  # noqa: BLE001 - the mission builds the map itself and reports the error
            result = (key, False, f"{type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}")
        try:
            _send(stdout, result)
        except (BrokenPipeError, OSError):
            return


if __name__ == "__main__":
    _serve(float(sys.argv[1]) if len(sys.argv) > 1 else IDLE_EXIT)
