"""What keeps a training run's files safe: the lock on the log directory, the stop on SIGTERM,
SIGHUP or Ctrl-C, atomic writes of models, checkpoints and evaluations, and the SAC replay
buffer in a format that loads without unpickling.

* **One run per folder.**  :class:`RunLock` holds ``DIR/train.lock`` with ``fcntl.flock`` for
  as long as the run lives (the kernel releases it when the process dies, however it dies);
  the file records the holder's process id, host and start time for the message a second run
  gets.  A lock file left by a run that is gone is taken over, with a note.
* **Stopping loses nothing.**  :class:`StopSignals` turns the first SIGTERM, SIGHUP or SIGINT
  into a request that the training callback sees at the next step; training then ends, and
  ``train()`` saves a checkpoint (and SAC's replay buffer) to resume from.  A second signal
  interrupts at once (``KeyboardInterrupt``); every file is still whole, written atomically.
* **Atomic files.**  Every model, checkpoint, evaluation log and buffer is written to a
  temporary file in the same folder and moved into place with ``os.replace``
  (:func:`agents.atomic.write_atomic`).
* **Replay buffers without pickle.**  SB3 pickles its replay buffer (``.pkl``), and loading a
  pickle can run code.  food-fetch train writes the buffer's arrays to ``.npz`` and reads them
  back with ``allow_pickle=False``; a ``.pkl`` buffer is loaded only when the user says it is
  trusted (``--trust-replay-buffer``).

SB3 is imported only inside the functions (the ``train`` extra).
"""

from __future__ import annotations

import contextlib
import errno
import io
import json
import os
import signal
import socket
import sys
import time
from pathlib import Path
from typing import Any

from agents.atomic import write_atomic

try:
    import fcntl
except ImportError:  # not POSIX: the lock falls back to the process id in the file
    fcntl = None  # type: ignore[assignment]

LOCK_NAME = "train.lock"
STOP_SIGNALS: tuple[int, ...] = tuple(
    getattr(signal, name) for name in ("SIGTERM", "SIGHUP", "SIGINT") if hasattr(signal, name))
BUFFER_FORMAT = "food-fetch replay buffer 1"
BUFFER_ARRAYS: tuple[str, ...] = ("observations", "next_observations", "actions", "rewards",
                                  "dones", "timeouts")


def _error(message: str) -> Exception:
    from agents.train import TrainError  # here: agents.train imports this module

    return TrainError(message)


# ---------------------------------------------------------------------------- atomic files
def save_model_atomic(model: Any, path: Path) -> None:
    """SB3's ``model.save`` into memory, then atomically to ``path``."""
    buf = io.BytesIO()
    model.save(buf)
    write_atomic(path, buf.getvalue())


# ------------------------------------------------------------------------------- the lock
def _describe(holder: dict[str, Any]) -> str:
    return (f"process {holder.get('pid', '?')} on {holder.get('host', '?')}, started "
            f"{holder.get('started', '?')}")


def _read_holder(path: Path) -> dict[str, Any]:
    try:
        holder = json.loads(path.read_text())
    except (OSError, ValueError, UnicodeDecodeError):
        return {}
    return holder if isinstance(holder, dict) else {}


def _pid_alive(pid: Any) -> bool:
    if not isinstance(pid, int) or pid <= 0:
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True  # someone else's process
    return True


def _try_flock(fd: int) -> bool | None:
    """True: locked; False: another process holds it; None: this file system has no flock."""
    if fcntl is None:
        return None
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError as exc:
        if exc.errno in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES):
            return False
        if exc.errno in (errno.ENOLCK, errno.EOPNOTSUPP, errno.EINVAL):
            return None
        raise
    return True


def _in_use(log_dir: Path, holder: dict[str, Any]) -> Exception:
    return _error(f"--log-dir {str(log_dir)!r} is in use by another food-fetch train run "
                  f"({_describe(holder)}): wait for it to end, or choose another --log-dir")


def check_unlocked(log_dir: Path) -> None:
    """TrainError when a live run holds ``log_dir``'s lock; creates and changes nothing."""
    path = log_dir / LOCK_NAME
    try:
        fd = os.open(path, os.O_RDONLY | os.O_CLOEXEC)
    except OSError:
        return  # no lock file (or no folder): nobody holds it
    try:
        state = _try_flock(fd)
        if state is False or (state is None and _held_without_flock(path)):
            raise _in_use(log_dir, _read_holder(path))
    finally:
        os.close(fd)  # closing drops a lock this check took


def _held_without_flock(path: Path) -> bool:
    """Without flock, a lock file is live when its process runs (on this host) or when it
    names another host, whose processes cannot be seen from here."""
    holder = _read_holder(path)
    if holder.get("host") != socket.gethostname():
        return bool(holder)
    return _pid_alive(holder.get("pid")) and holder.get("pid") != os.getpid()


class RunLock:
    """The lock on a log directory, held from :meth:`acquire` until :meth:`release`."""

    def __init__(self, log_dir: Path, fd: int) -> None:
        self.path = log_dir / LOCK_NAME
        self._fd: int | None = fd

    @classmethod
    def acquire(cls, log_dir: Path, command: list[str] | None = None) -> RunLock:
        """Create ``log_dir`` if needed and lock it; TrainError naming the holder when
        another run has it.  A lock file whose run is gone is taken over, with a note."""
        log_dir.mkdir(parents=True, exist_ok=True)
        path = log_dir / LOCK_NAME
        for _ in range(20):  # retried while a finishing run removes the file under us
            fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o644)
            state = _try_flock(fd)
            if state is False or (state is None and _held_without_flock(path)):
                holder = _read_holder(path)
                os.close(fd)
                raise _in_use(log_dir, holder)
            try:
                same = os.path.samestat(os.fstat(fd), os.stat(path))
            except FileNotFoundError:
                same = False
            if same:
                lock = cls(log_dir, fd)
                lock._record(command)
                return lock
            os.close(fd)
        raise _error(f"cannot lock --log-dir {str(log_dir)!r}: its lock file keeps changing")

    def _record(self, command: list[str] | None) -> None:
        earlier = _read_holder(self.path)
        if earlier.get("pid") is not None:
            print(f"food-fetch train: note: taking over the lock of {_describe(earlier)}, "
                  "which is no longer running", file=sys.stderr)
        holder = {"pid": os.getpid(), "host": socket.gethostname(),
                  "started": time.strftime("%Y-%m-%d %H:%M:%S"),
                  "command": list(command) if command is not None else list(sys.argv)}
        assert self._fd is not None
        os.ftruncate(self._fd, 0)
        os.pwrite(self._fd, json.dumps(holder).encode() + b"\n", 0)
        os.fsync(self._fd)

    def release(self) -> None:
        """Remove the lock file, then unlock (in that order: a run waiting on the file finds
        it gone and creates a new one)."""
        if self._fd is None:
            return
        with contextlib.suppress(OSError):
            self.path.unlink()
        os.close(self._fd)
        self._fd = None


# ----------------------------------------------------------------------------- stop signals
class StopSignals:
    """While active, the first SIGTERM, SIGHUP or SIGINT is recorded in :attr:`signum` (the
    training callback then stops at the next step); a second raises KeyboardInterrupt.
    Installed only in the main thread, where Python delivers signals."""

    def __init__(self) -> None:
        self.signum: int | None = None
        self._old: dict[int, Any] = {}

    def _handle(self, signum: int, _frame: Any) -> None:
        if self.signum is not None:
            raise KeyboardInterrupt
        self.signum = signum

    @property
    def name(self) -> str:
        return signal.Signals(self.signum).name if self.signum is not None else ""

    def __enter__(self) -> StopSignals:
        for sig in STOP_SIGNALS:
            try:
                self._old[sig] = signal.signal(sig, self._handle)
            except ValueError:  # not the main thread: signals keep their handlers
                break
        return self

    def __exit__(self, *exc: object) -> None:
        for sig, old in self._old.items():
            signal.signal(sig, old)
        self._old.clear()


# -------------------------------------------------------------------------------- callbacks
def stoppable(callbacks: list[Any], stop: StopSignals) -> Any:
    """SB3's CallbackList that ends training at the first step after a stop signal, without
    running the other callbacks there (an evaluation would delay the stop)."""
    from stable_baselines3.common.callbacks import CallbackList

    class Stoppable(CallbackList):
        def _on_step(self) -> bool:
            if stop.signum is None:
                return super()._on_step()
            loc = self.locals
            if "replay_buffer" in loc and "buffer_actions" in loc:
                # SAC stores this step's transition only after the callbacks: store it now,
                # as SB3 would have, so the checkpoint's buffer holds every counted step.
                self.model._update_info_buffer(loc["infos"], loc["dones"])
                self.model._store_transition(loc["replay_buffer"], loc["buffer_actions"],
                                             loc["new_obs"], loc["rewards"], loc["dones"],
                                             loc["infos"])
            return False

    return Stoppable(callbacks)


def checkpoint_path(save_dir: Path, steps: int, kind: str = "", ext: str = "zip") -> Path:
    """CheckpointCallback's names: ``rl_model_<n>_steps.zip`` and
    ``rl_model_replay_buffer_<n>_steps.npz`` (npz: see :func:`save_replay_buffer`)."""
    return save_dir / f"rl_model_{kind}{steps}_steps.{ext}"


def save_checkpoint(model: Any, save_dir: Path) -> Path:
    """The model (and SAC's replay buffer) at its current step, atomically; the model's
    path."""
    save_dir.mkdir(parents=True, exist_ok=True)
    steps = int(model.num_timesteps)
    path = checkpoint_path(save_dir, steps)
    save_model_atomic(model, path)
    if getattr(model, "replay_buffer", None) is not None:
        save_replay_buffer(model.replay_buffer,
                           checkpoint_path(save_dir, steps, "replay_buffer_", "npz"))
    return path


def checkpoint_callback(save_freq: int, save_dir: Path) -> Any:
    """SB3's CheckpointCallback, writing through :func:`save_checkpoint` (atomic; the replay
    buffer as npz)."""
    from stable_baselines3.common.callbacks import CheckpointCallback

    class AtomicCheckpoint(CheckpointCallback):
        def _on_step(self) -> bool:
            if self.n_calls % self.save_freq == 0:
                save_checkpoint(self.model, save_dir)
            return True

    return AtomicCheckpoint(save_freq=save_freq, save_path=str(save_dir))


def eval_callback(eval_env: Any, log_dir: Path, **kwargs: Any) -> Any:
    """SB3's EvalCallback logging to ``log_dir`` (evaluations.npz, best_model.zip), writing
    both atomically: to temporary names, then moved into place."""
    from stable_baselines3.common.callbacks import EvalCallback

    class AtomicEval(EvalCallback):
        def _on_step(self) -> bool:
            if not (self.eval_freq > 0 and self.n_calls % self.eval_freq == 0):
                return super()._on_step()  # no evaluation at this step: nothing written
            final_log, final_best = self.log_path, self.best_model_save_path
            part_best = os.path.join(final_best, ".best.part")
            os.makedirs(part_best, exist_ok=True)
            self.log_path, self.best_model_save_path = final_log + ".part", part_best
            try:
                result = super()._on_step()
            finally:
                self.log_path, self.best_model_save_path = final_log, final_best
            if os.path.exists(final_log + ".part.npz"):
                os.replace(final_log + ".part.npz", final_log + ".npz")
            if os.path.exists(os.path.join(part_best, "best_model.zip")):
                os.replace(os.path.join(part_best, "best_model.zip"),
                           os.path.join(final_best, "best_model.zip"))
            with contextlib.suppress(OSError):
                os.rmdir(part_best)
            return result

    return AtomicEval(eval_env, log_path=str(log_dir), best_model_save_path=str(log_dir),
                      **kwargs)


# ---------------------------------------------------------------------------- replay buffer
def save_replay_buffer(buffer: Any, path: Path) -> None:
    """The filled part of an SB3 ReplayBuffer as plain arrays (npz, no pickle), atomically."""
    import numpy as np

    n = buffer.buffer_size if buffer.full else buffer.pos
    arrays = {k: getattr(buffer, k)[:n] for k in BUFFER_ARRAYS
              if getattr(buffer, k, None) is not None}
    meta = {"format": BUFFER_FORMAT, "pos": int(buffer.pos), "full": bool(buffer.full),
            "buffer_size": int(buffer.buffer_size), "n_envs": int(buffer.n_envs)}
    out = io.BytesIO()
    np.savez(out, meta=np.array(json.dumps(meta)), **arrays)
    write_atomic(path, out.getvalue())


def load_replay_buffer(buffer: Any, path: Path) -> None:
    """Fill an SB3 ReplayBuffer from :func:`save_replay_buffer`'s npz (read without pickle);
    TrainError when the file is not such a buffer or does not fit this one."""
    import numpy as np

    bad = f"the replay buffer {str(path)!r}"
    try:
        with np.load(path, allow_pickle=False) as npz:
            meta = json.loads(str(npz["meta"]))
            arrays = {k: npz[k] for k in npz.files if k != "meta"}
    except (OSError, ValueError, KeyError, EOFError) as exc:
        raise _error(f"{bad} is not one food-fetch train wrote: {exc}") from None
    if not isinstance(meta, dict) or meta.get("format") != BUFFER_FORMAT:
        raise _error(f"{bad} is not one food-fetch train wrote")
    if meta.get("n_envs") != buffer.n_envs:
        raise _error(f"bad hyperparameter n_envs={buffer.n_envs}: {bad} holds "
                     f"{meta.get('n_envs')}")
    if meta.get("buffer_size") != buffer.buffer_size:
        raise _error(f"{bad} holds {meta.get('buffer_size')} steps per env, the model's "
                     f"buffer {buffer.buffer_size}")
    n = buffer.buffer_size if meta.get("full") else int(meta.get("pos", -1))
    for key in BUFFER_ARRAYS:
        target = getattr(buffer, key, None)
        if target is None:
            continue
        got = arrays.get(key)
        if got is None or got.shape != (n, *target.shape[1:]):
            raise _error(f"{bad}: its {key} do not fit the model's buffer")
        target[:n] = got
    buffer.pos, buffer.full = int(meta["pos"]) % buffer.buffer_size, bool(meta["full"])


def find_replay_buffer(checkpoint: Path) -> Path | None:
    """The buffer saved beside a checkpoint (``rl_model_<n>_steps.zip``): the npz this module
    writes, else SB3's pickle (``.pkl``); None when there is neither."""
    stem = checkpoint.stem
    if stem.endswith("_steps") and "_" in stem[:-6]:
        prefix, n = stem[:-6].rsplit("_", 1)
        for ext in ("npz", "pkl"):
            cand = checkpoint.with_name(f"{prefix}_replay_buffer_{n}_steps.{ext}")
            if cand.exists():
                return cand
    return None


# ------------------------------------------------------------------------ an earlier run
# The files a run writes under its log dir, which --overwrite removes before a new run.
RUN_FILES: tuple[str, ...] = ("model.zip", "config.yml", "progress.csv",
                              "eval/evaluations.npz", "eval/best_model.zip")
RUN_GLOBS: tuple[str, ...] = ("monitor/*.monitor.csv", "checkpoints/rl_model_*_steps.zip",
                              "checkpoints/rl_model_replay_buffer_*_steps.npz",
                              "checkpoints/rl_model_replay_buffer_*_steps.pkl",
                              "events.out.tfevents.*")


def earlier_run(log_dir: Path) -> str | None:
    """What of an earlier run ``log_dir`` holds (its model, config or checkpoints), or None."""
    if not log_dir.is_dir():
        return None
    for name in ("model.zip", "config.yml"):
        if (log_dir / name).is_file():
            return name
    ckpts = sorted((log_dir / "checkpoints").glob("rl_model_*_steps.zip"))
    return f"checkpoints/{ckpts[0].name}" if ckpts else None


def remove_earlier_run(log_dir: Path) -> int:
    """Delete the files an earlier run wrote under ``log_dir`` (and only those); how many."""
    paths = [log_dir / name for name in RUN_FILES if (log_dir / name).is_file()]
    for pattern in RUN_GLOBS:
        paths += [p for p in log_dir.glob(pattern) if p.is_file()]
    for p in paths:
        p.unlink()
    return len(paths)
