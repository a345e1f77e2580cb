"""Worker processes that the study's process can kill: where every computed cell runs.

A solve that calls `os._exit`, is killed by a signal (the OOM killer, a segfault) or never returns ends its
worker, not the study: the parent waits on each worker with the cell's time limit, and a worker that dies or
runs past it is killed and replaced, its task getting the outcome that says so.  The pool (`pool`) is forked
from this process when first needed and serves task after task, so compiled kernels stay warm and the serial
timed pass warms up and times in one process (`Pool.run_one` takes the first idle worker).  A dead worker
names its one task; only when other workers were busy beside it (the OOM killer picks the largest process) is
the task run again alone before it is called the culprit.  A worker prints to stderr through a pipe that the
study's process drains as it waits (passing the bytes on to its own stderr at once), so the last error line a
task printed (LAMMPS's "ERROR: ..." before it aborts, say) can be put into the reason of its failure; a worker
ignores Ctrl-C and exits when the study's process has gone.  Each task starts from the worker's state as it
was forked: its working folder, environment, signal handlers and file descriptors 0-2 are put back after every
task (a worker whose state cannot be put back ends once it has replied), and the processes a task started end
with it: a worker leads a process group of its own, whose other members are killed when a task ends and with
the worker when it is retired.
"""

from __future__ import annotations

import atexit
import contextlib
import ctypes
import io
import multiprocessing
import os
import pickle
import re
import signal
import sys
import time
from collections import deque
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field
from multiprocessing.connection import Connection, wait
from typing import Any

from pcverify.harness.run.interrupt import STUDY_PID, deferred_interrupts, ignore_sigint_in_worker

STOP_SIGNALS = {signal.SIGINT, signal.SIGTERM}
ERROR_LINE = re.compile(r"\b(ERROR|Error|error|FATAL|Fatal|fatal|Abort|abort)\b")  # a line that says what failed
OUTPUT_KEPT = 16384  # bytes of a task's output kept to find its last error line
_FORK = multiprocessing.get_context("fork")  # a worker inherits the imported modules: no start-up import
_KEEP: list[Any] = []  # a worker's inherited std streams, kept so that their buffers are never flushed twice


@dataclass(frozen=True)
class Outcome:
    """How a task ended: `value` when it returned (kind "returned"), else why not (kind "died", "timed-out"
    or "raised": the worker could not run it, e.g. its arguments or result would not pickle)."""

    kind: str
    value: Any = None
    reason: str = ""
    error_line: str = ""  # the last line the task printed that names an error (`ERROR_LINE`), if any


Task = tuple[Any, Callable[..., Any], tuple[Any, ...]]  # (tag, function, arguments)


@dataclass(eq=False)
class _Worker:
    process: Any
    conn: Connection
    tag: Any = None
    seq: int = 0
    started: float = 0.0
    shared: bool = False  # another worker was busy while this task ran
    task: Task | None = None
    output: int = -1  # the read end of the pipe that is the worker's stderr (and stdout)
    printed: bytearray = field(default_factory=bytearray)  # the end of what the current task printed


@dataclass
class Pool:
    """Worker processes of this process, created on demand and reused; `world` names the state they were
    forked from (the caller's sys.path and registrations), and the pool is replaced when it changes."""

    world: Any = None
    pid: int = field(default_factory=os.getpid)
    workers: list[_Worker] = field(default_factory=list)
    _seq: int = 0

    def run_one(self, fn: Callable[..., Any], args: tuple[Any, ...], time_limit: float) -> Outcome:
        """Run `fn(*args)` in the first idle worker (the same one call after call while it lives)."""
        return list(self.run([(0, fn, args)], 1, time_limit))[0][1]

    def run(self, tasks: Iterable[Task], width: int, time_limit: float) -> Iterator[tuple[Any, Outcome]]:
        """(tag, Outcome) of every task, in completion order, with at most `width` running at once, each
        killed after `time_limit` seconds.  A task whose worker died while others ran is run again alone
        before it is reported as died.  Leaving the loop early (an interrupt) kills the busy workers."""
        queue: deque[Task] = deque(tasks)
        suspects: deque[Task] = deque()
        busy: list[_Worker] = []
        try:
            while queue or suspects or busy:
                if suspects:
                    if not busy:
                        self._send(self._idle(busy), suspects.popleft(), busy)
                else:
                    while queue and len(busy) < width:
                        self._send(self._idle(busy), queue.popleft(), busy)
                now = time.monotonic()
                timeout = max(0.0, min(w.started + time_limit for w in busy) - now)
                ready = set(wait([w.conn for w in busy] + [w.process.sentinel for w in busy]
                                 + [w.output for w in self.workers if w.output >= 0], timeout))
                for w in list(self.workers):
                    if w.output in ready:
                        _drain(w)
                for w in list(busy):
                    if w.conn in ready or w.process.sentinel in ready:
                        outcome = self._collect(w)
                    elif time.monotonic() - w.started >= time_limit:
                        self._retire(w)  # what it printed is drained first
                        outcome = Outcome("timed-out", reason=f"exceeded the time limit of {time_limit:g} s "
                                          "(its worker process was killed)", error_line=_error_line(w.printed))
                    else:
                        continue
                    busy.remove(w)
                    task, w.task = w.task, None
                    if outcome.kind == "died" and w.shared:
                        suspects.append(task)  # maybe a neighbour's fault: run it again, alone
                        continue
                    yield w.tag, outcome
        finally:
            for w in busy:  # abandoned tasks (an interrupt): their workers are killed, not left computing
                self._retire(w)

    def _idle(self, busy: list[_Worker]) -> _Worker:
        for w in self.workers:
            if w not in busy and w.process.is_alive():
                return w
            if w not in busy:
                self._retire(w)
                return self._idle(busy)
        return self._start()

    def _start(self) -> _Worker:
        for stream in (sys.stdout, sys.stderr):  # nothing of this process's buffers is written twice
            with contextlib.suppress(Exception):
                stream.flush()
        mine, theirs = _FORK.Pipe()
        output, stderr = os.pipe()
        os.set_blocking(output, False)
        others = [w.conn for w in self.workers]
        closed = [output, *(w.output for w in self.workers if w.output >= 0)]  # the worker's: only its stderr
        process = _FORK.Process(target=_serve, args=(theirs, mine, others, os.getpid(), stderr, closed),
                                name="pcverify-worker")
        # Ctrl-C and SIGTERM wait until the fork is done: the study's handler raises KeyboardInterrupt, which
        # inside the fork's own hooks (logging's at-fork lock release) is printed as a traceback and lost
        # (and, delivered to another thread, they are only remembered until the fork is done)
        blocked = signal.pthread_sigmask(signal.SIG_BLOCK, STOP_SIGNALS)
        try:
            with deferred_interrupts():
                process.start()
        finally:
            signal.pthread_sigmask(signal.SIG_SETMASK, blocked)
        theirs.close()
        os.close(stderr)
        worker = _Worker(process, mine, output=output)
        self.workers.append(worker)
        return worker

    def _send(self, w: _Worker, task: Task, busy: list[_Worker]) -> None:
        tag, fn, args = task
        self._seq += 1
        _drain(w)  # what it printed since its last task is not this task's
        w.tag, w.seq, w.task, w.started, w.shared = tag, self._seq, task, time.monotonic(), bool(busy)
        w.printed.clear()
        for other in busy:
            other.shared = True
        busy.append(w)
        try:
            blob = pickle.dumps((fn, args), protocol=pickle.HIGHEST_PROTOCOL)
        except Exception as exc:  # noqa: BLE001 - arguments a worker cannot receive: that task's outcome
            blob = pickle.dumps((_refuse, (f"its arguments cannot be sent to a worker ({describe_exception(exc)})",)))
        try:
            w.conn.send((w.seq, blob))
        except OSError:
            pass  # the worker died meanwhile: its sentinel says so

    def _collect(self, w: _Worker) -> Outcome:
        """The finished task's outcome: its reply, or how its worker died (with the last error line it printed)."""
        try:
            if w.conn.poll():
                seq, kind, payload = w.conn.recv()
                if seq == w.seq:
                    _drain(w)  # everything it printed before replying is in the pipe by now
                    line = _error_line(w.printed)
                    return (Outcome("returned", payload, error_line=line) if kind == "ok"
                            else Outcome("raised", reason=payload, error_line=line))
        except (EOFError, OSError, pickle.UnpicklingError, ValueError, TypeError):
            pass
        with contextlib.suppress(Exception):
            w.process.join(1.0)  # its exit code, and the last of its output in the pipe (drained by _retire)
        self._retire(w)
        return Outcome("died", reason=f"its worker process ended without a result "
                                      f"({exit_description(w.process.exitcode)})", error_line=_error_line(w.printed))

    def _retire(self, w: _Worker) -> None:
        """Kill a worker and the processes of its group (its tasks' children; no-op if they have ended) and forget
        it (what it printed passed on first)."""
        _drain(w)
        with contextlib.suppress(Exception):
            if w.process.pid is not None and os.getpgid(w.process.pid) == w.process.pid:
                os.killpg(w.process.pid, signal.SIGKILL)
        with contextlib.suppress(Exception):
            if w.process.is_alive():
                w.process.kill()
            w.process.join(5.0)
        with contextlib.suppress(Exception):
            w.conn.close()
        if w.output >= 0:
            with contextlib.suppress(OSError):
                os.close(w.output)
            w.output = -1
        if w in self.workers:
            self.workers.remove(w)

    def close(self) -> None:
        """Stop every worker of this pool."""
        for w in list(self.workers):
            self._retire(w)


def _drain(w: _Worker) -> None:
    """Pass on what worker `w` printed to this process's stderr (file descriptor 2, as if the worker had written
    there) and keep its end for the current task's error line."""
    while w.output >= 0:
        try:
            data = os.read(w.output, 65536)
        except (BlockingIOError, InterruptedError):
            return
        except OSError:
            data = b""
        if not data:  # the worker and everything that held its stderr have ended
            with contextlib.suppress(OSError):
                os.close(w.output)
            w.output = -1
            return
        w.printed += data
        del w.printed[:-OUTPUT_KEPT]
        view = memoryview(data)
        with contextlib.suppress(OSError):
            while view:
                view = view[os.write(2, view):]


def _error_line(printed: bytes) -> str:
    """The last line of `printed` that names an error (`ERROR_LINE`), stripped; "" if none."""
    for line in reversed(bytes(printed).decode(errors="backslashreplace").splitlines()):
        if ERROR_LINE.search(line):
            return " ".join(line.split())[:500]
    return ""


def exit_description(code: int | None) -> str:
    """What a process's exit code says: "killed by signal 9, SIGKILL" or "exit code 7"."""
    if code is None:
        return "no exit status"
    if code < 0:
        try:
            name = signal.Signals(-code).name
        except ValueError:
            name = "an unknown signal"
        return f"killed by signal {-code}, {name}"
    return f"exit code {code}"


_POOL: list[Pool] = []


def pool(world: Any) -> Pool:
    """This process's pool, replaced (its workers stopped) when `world` differs from the one its workers were
    forked from.  A forked child never uses its parent's pool."""
    if _POOL and (_POOL[0].pid != os.getpid() or _POOL[0].world != world):
        old = _POOL.pop()
        if old.pid == os.getpid():
            old.close()
    if not _POOL:
        _POOL.append(Pool(world))
    return _POOL[0]


@atexit.register
def _close_pool() -> None:
    if _POOL and _POOL[0].pid == os.getpid():
        _POOL[0].close()


def describe_exception(exc: BaseException) -> str:
    """`Type: message` of an exception on one line, even when its str() raises."""
    try:
        text = " ".join(str(exc).split())
    except Exception:  # noqa: BLE001 - a hostile exception's __str__
        text = "(its message cannot be shown)"
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__


def _refuse(reason: str) -> Any:
    raise RuntimeError(reason)


def _serve(conn: Connection, mine: Connection, others: list[Connection], parent: int, stderr: int,
           closed: list[int]) -> None:
    """A worker's life: receive (seq, pickled (fn, args)), reply (seq, "ok", value) or (seq, "error", text),
    until the pipe closes.  Its stderr is the pipe `stderr`; `closed` are the parent's read ends it inherited."""
    _die_with(parent)
    os.dup2(stderr, 2)
    os.close(stderr)
    for fd in closed:
        with contextlib.suppress(OSError):
            os.close(fd)
    mine.close()
    for other in others:  # the parent's ends of the other workers' pipes: theirs alone
        with contextlib.suppress(OSError):
            other.close()
    with contextlib.suppress(OSError):
        os.setpgid(0, 0)  # a group of its own: the processes its tasks start are found and ended by it
    _output_to_stderr()
    signal.signal(signal.SIGTERM, signal.SIG_DFL)  # not the study's handler, inherited by the fork
    os.environ[STUDY_PID] = str(parent)
    ignore_sigint_in_worker()  # Ctrl-C is the study's to handle; exit when the study's process is gone
    signal.pthread_sigmask(signal.SIG_UNBLOCK, STOP_SIGNALS)  # blocked by the study's process for the fork
    state = _State.now()
    while True:
        try:
            seq, blob = conn.recv()
        except (EOFError, OSError):
            os._exit(0)
        try:
            fn, args = pickle.loads(blob)
            reply = (seq, "ok", fn(*args))
        except BaseException as exc:  # noqa: BLE001 - whatever a task raises is its outcome, the worker goes on
            reply = (seq, "error", describe_exception(exc))
        end_group()  # the task's own processes end with it (they may hold the study's stderr)
        clean = state.restore()
        try:
            conn.send(reply)
        except (EOFError, OSError):
            os._exit(0)
        except BaseException as exc:  # noqa: BLE001 - a result that does not pickle
            conn.send((seq, "error", f"its result cannot be sent back ({describe_exception(exc)})"))
        for stream in (sys.stdout, sys.stderr):
            with contextlib.suppress(Exception):
                stream.flush()
        if not clean:
            os._exit(0)  # retired: the pool starts a fresh worker for the next task


@dataclass
class _State:
    """What a task may change in its worker and the next task must not see: the working folder, the environment,
    the signal handlers, file descriptors 0-2 (copies kept on descriptors of their own) and Python's std
    streams."""

    cwd: str
    environ: dict[str, str]
    fds: list[int]
    streams: tuple[Any, Any, Any]
    handlers: dict[signal.Signals, Any]

    @classmethod
    def now(cls) -> _State:
        handlers = {sig: signal.getsignal(sig) for sig in signal.valid_signals()
                    if sig not in (signal.SIGKILL, signal.SIGSTOP)}
        return cls(os.getcwd(), dict(os.environ), [os.dup(fd) for fd in (0, 1, 2)], (sys.stdin, sys.stdout, sys.stderr),
                   {sig: h for sig, h in handlers.items() if h is not None})

    def restore(self) -> bool:
        """Put the worker back as it was; False when that failed (a copy of a descriptor closed by the task)."""
        try:
            os.chdir(self.cwd)
            for sig, handler in self.handlers.items():
                if signal.getsignal(sig) is not handler:
                    signal.signal(sig, handler)
            if dict(os.environ) != self.environ:
                os.environ.clear()
                os.environ.update(self.environ)
            for fd, copy in zip((0, 1, 2), self.fds, strict=True):
                if not (_is_open(fd) and os.path.sameopenfile(fd, copy)):
                    os.dup2(copy, fd)
            sys.stdin = self.streams[0]
            if (sys.stdout, sys.stderr) != self.streams[1:] or any(s.closed for s in self.streams[1:]):
                _output_to_stderr()  # fresh streams on the descriptors put back
                self.streams = (sys.stdin, sys.stdout, sys.stderr)
            return True
        except (OSError, ValueError):
            return False


def _is_open(fd: int) -> bool:
    try:
        os.fstat(fd)
    except OSError:
        return False
    return True


def end_group() -> None:
    """Kill every other process of this process's group (what the task started: an outside code left running,
    a helper holding stderr) and reap those that are its children; Linux (/proc) only, elsewhere nothing."""
    me = os.getpid()
    if os.getpgid(0) != me:
        return
    try:
        entries = os.listdir("/proc")
    except OSError:
        return
    for entry in entries:
        if not entry.isdigit() or int(entry) == me:
            continue
        try:
            with open(f"/proc/{entry}/stat", "rb") as fh:
                fields = fh.read().rsplit(b")", 1)[1].split()
        except (OSError, IndexError):
            continue
        if len(fields) > 2 and int(fields[2]) == me:  # after the name: state, ppid, pgrp
            with contextlib.suppress(OSError):
                os.kill(int(entry), signal.SIGKILL)
    with contextlib.suppress(ChildProcessError, OSError):
        while os.waitpid(-1, os.WNOHANG)[0] > 0:
            pass


PR_SET_PDEATHSIG = 1  # prctl(2): the signal this process gets when the thread that forked it ends


def _die_with(parent: int) -> None:
    """In a worker: be killed the moment the study's process ends, even by SIGKILL and even in compiled code that
    holds the interpreter lock: Linux's prctl (through the process's own symbols: no library search per fork);
    elsewhere the worker's watchdog thread (`interrupt.ignore_sigint_in_worker`) notices once it gets to run."""
    if sys.platform.startswith("linux"):
        with contextlib.suppress(Exception):
            ctypes.CDLL(None).prctl(PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
    if os.getppid() != parent:  # the study's process ended before the request was made
        os._exit(0)


def _output_to_stderr() -> None:
    """In a worker: file descriptor 1 becomes a copy of 2 (so C-level prints go to stderr too), and Python's
    sys.stdout and sys.stderr are fresh streams on them (the inherited ones may hold another thread's lock or
    the parent's unflushed output)."""
    _KEEP.extend([sys.stdout, sys.stderr])
    os.dup2(2, 1)
    sys.stderr = io.TextIOWrapper(io.FileIO(2, "w", closefd=False), line_buffering=True, errors="backslashreplace")
    sys.stdout = sys.stderr


@contextlib.contextmanager
def output_to_stderr() -> Iterator[None]:
    """Within the block, whatever this process prints (Python's print and C-level writes to file descriptor
    1) goes to stderr, so a plugin's output never mixes with the JSON a command prints afterwards."""
    with contextlib.suppress(Exception):
        sys.stdout.flush()
    try:
        saved = os.dup(1)
    except OSError:  # no stdout at all: nothing to protect
        saved = None
    if saved is not None:
        os.dup2(2, 1)
    try:
        with contextlib.redirect_stdout(sys.stderr):
            yield
    finally:
        with contextlib.suppress(Exception):
            sys.stdout.flush()  # a plugin's writes to the real sys.stdout: out to stderr, before fd 1 is back
        if saved is not None:
            os.dup2(saved, 1)
            os.close(saved)
