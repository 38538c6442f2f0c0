"""The node entry point: `NodeBuilder` reads the start-up inputs, opens
the session, declares everything, runs the node's setup and keeps the
node up until it is stopped. `NodeRunner` is the handle node code gets."""

from __future__ import annotations

import asyncio
import inspect
import logging
import os
import signal
import sys
from typing import Any, Callable, Iterable, List, Optional

from .action_server import DEFAULT_RESULT_RETENTION
from .declare import declare_all
from .errors import PeppyError, StartupError
from .runner import NodeRunner
from .spec import NodeDescriptor
from .standalone import StandaloneConfig
from .startup import DEFAULT_SHUTDOWN_GRACE, Startup, config_file_from_env, grace_from_env, grace_secs, load

__all__ = ["NodeBuilder", "NodeRunner", "StandaloneConfig"]

USE_SIM_TIME_FLAG = "--use-sim-time"
"""The command-line flag a standalone node follows sim time with."""

log = logging.getLogger("peppy")

Setup = Callable[[Any, NodeRunner], Any]
"""`async def setup(params, node_runner)`, returning the tasks it started (or None)."""

_UNSET: Any = object()


class NodeBuilder:
    """Builds and runs a node: reads its start-up inputs, opens one Zenoh
    session, declares every publisher, subscription and service up front,
    runs the node's setup code, then keeps the node up until SIGINT or
    SIGTERM (or `NodeRunner.stop()`, or its cancellation token cancelled).
    Stopping cancels the token, runs the shutdown hooks, closes messaging,
    then cancels the node's tasks."""

    def __init__(self, descriptor: NodeDescriptor) -> None:
        self._descriptor = descriptor
        self._args: Optional[List[str]] = None
        self._runtime_config: Any = _UNSET
        self._retention = DEFAULT_RESULT_RETENTION
        self._standalone: Optional[StandaloneConfig] = None
        self._grace: Optional[float] = None

    def with_args(self, args: Iterable[str]) -> "NodeBuilder":
        """Uses these command-line arguments (without the program name) instead of `sys.argv[1:]`."""
        self._args = list(args)
        return self

    def with_runtime_config(self, path: Optional[str]) -> "NodeBuilder":
        """Uses this runtime-config file (or none) instead of `PEPPY_RUNTIME_CONFIG`."""
        self._runtime_config = path
        return self

    def standalone(self, config: StandaloneConfig) -> "NodeBuilder":
        """Defaults for a start without a launcher (each replaced by its
        command-line flag); a launcher's runtime config wins."""
        self._standalone = config
        return self

    def shutdown_grace(self, seconds: float) -> "NodeBuilder":
        """The window shutdown hooks run in when the runtime config does not
        set one (default 5 s); `PEPPY_SHUTDOWN_GRACE_SECS` overrides both."""
        self._grace = grace_secs(seconds, "NodeBuilder.shutdown_grace")
        return self

    def action_result_retention(self, seconds: float) -> "NodeBuilder":
        """How long exposed actions keep a finished goal's result (default 30 s)."""
        self._retention = float(seconds)
        return self

    def _parameters(self, startup: Startup) -> Any:
        cls = self._descriptor.parameters
        data = startup.parameters
        if data is None:
            data = {}
        if not isinstance(data, dict):
            raise StartupError(
                f"invalid parameters:\n  - parameters are an object of values, found {type(data).__name__}"
            )
        if cls is None:
            return data
        try:
            return cls.from_json(data)
        except ValueError as e:
            raise StartupError(f"invalid parameters:\n  - {e}") from None

    async def start(self, setup: Optional[Setup] = None) -> NodeRunner:
        """Starts the node in the running loop and returns its runner, with
        `setup` run and its tasks adopted (tests, embedding). Call
        `await runner.shutdown()` when done."""
        import zenoh

        config_file = config_file_from_env() if self._runtime_config is _UNSET else self._runtime_config
        args = list(sys.argv[1:] if self._args is None else self._args)
        sim_flag = USE_SIM_TIME_FLAG in args
        args = [a for a in args if a != USE_SIM_TIME_FLAG]
        standalone = self._standalone if not config_file else None
        links_given = any(a.split("=", 1)[0] in ("--link", "--vacant-link", "--bind") for a in args)
        if standalone is not None:
            args += standalone.flags(args)
        try:
            startup = load(self._descriptor, args, config_file)
        finally:
            for path in standalone.written if standalone is not None else ():
                try:
                    os.remove(path)
                except OSError:
                    pass
        if not config_file and standalone is not None and not links_given:
            # The code's links say where their producers run.
            startup.producer_cores = dict(standalone.cores)
        if not config_file:
            # A standalone start: the flag, else the code, says.
            wanted = standalone.use_sim_time if standalone is not None else None
            if sim_flag or wanted:
                startup.use_sim_time = True
            elif wanted is False:
                startup.use_sim_time = False
        # The environment, then the launcher's config, then the code; a
        # standalone plan carries only a default, so the code goes first there.
        planned = startup.shutdown_grace_secs
        chosen = (planned or self._grace) if config_file else (self._grace or planned)
        startup.shutdown_grace_secs = grace_from_env() or chosen or DEFAULT_SHUTDOWN_GRACE
        parameters = self._parameters(startup)
        config = startup.endpoints.zenoh_config()
        loop = asyncio.get_running_loop()
        try:
            session = await loop.run_in_executor(None, zenoh.open, config)
        except Exception as e:
            raise StartupError(f"cannot open the zenoh session: {e}") from None
        runner = NodeRunner(self._descriptor, startup, session, parameters)
        try:
            await declare_all(runner, self._retention)
        except BaseException:
            await runner.shutdown()
            raise
        log.info(
            "node up: %s:%s, instance %s, namespace %s",
            runner.node_name,
            runner.node_tag,
            runner.instance_id,
            runner.namespace,
        )
        if setup is not None:
            try:
                runner.adopt(await _call_setup(setup, parameters, runner))
            except BaseException:
                await runner.shutdown()
                raise
        return runner

    def run(self, setup: Setup) -> None:
        """Runs the node to completion. `setup(params, node_runner)` runs
        once (a function or an `async def`, returning the tasks it started,
        or None); a setup that fails is printed and the process exits 1
        after the node's shutdown. A stop by signal or token exits 0; a
        second signal while stopping exits at once with 128 + its number."""
        _init_logging()
        try:
            asyncio.run(self._run(setup))
        except KeyboardInterrupt:
            raise SystemExit(130) from None
        except PeppyError as e:
            print(f"error: {e}", file=sys.stderr)
            raise SystemExit(1) from None
        except Exception as e:
            log.error("the node failed: %r", e, exc_info=e)
            print(f"error: {e}", file=sys.stderr)
            raise SystemExit(1) from None

    async def _run(self, setup: Setup) -> None:
        runner = await self.start()
        loop = runner.loop
        installed = []
        for sig, why in ((signal.SIGINT, "interrupted"), (signal.SIGTERM, "terminated")):
            try:
                loop.add_signal_handler(sig, _on_signal, runner, why, int(sig))
                installed.append(sig)
            except (NotImplementedError, RuntimeError, ValueError):
                pass
        orphan_watch = loop.create_task(_stop_when_orphaned(runner))
        setup_task = loop.create_task(_call_setup(setup, runner.parameters, runner))
        stop_wait = loop.create_task(runner.stopped.wait())
        try:
            await asyncio.wait({setup_task, stop_wait}, return_when=asyncio.FIRST_COMPLETED)
            if setup_task.done():
                # A failing setup ends the node with its error.
                runner.adopt(setup_task.result())
                await stop_wait
            else:
                # Stopped during setup: setup is dropped, as the Rust runtime does.
                setup_task.cancel()
                await asyncio.gather(setup_task, return_exceptions=True)
        finally:
            orphan_watch.cancel()
            if not stop_wait.done():
                stop_wait.cancel()
            try:
                # The signal handlers stay while the hooks run: a second
                # signal ends the process at once.
                await runner.shutdown()
            finally:
                for sig in installed:
                    loop.remove_signal_handler(sig)


async def _stop_when_orphaned(runner: NodeRunner) -> None:
    """Stops the node once the process that started it is gone.

    A launcher gives its children a parent-death signal, but a Python node
    usually runs under `uv run`, which does not pass that on: without this
    a killed launcher would leave the interpreter running."""
    parent = os.getppid()
    if parent <= 1:
        return
    while True:
        await asyncio.sleep(1.0)
        if os.getppid() != parent:
            _stop_on(runner, "the process that started this node is gone")
            return


def _on_signal(runner: NodeRunner, why: str, signo: int) -> None:
    if runner.is_stopping():
        log.warning("%s again while stopping; exiting now", why)
        for stream in (sys.stdout, sys.stderr):
            try:
                stream.flush()
            except Exception:
                pass
        os._exit(128 + signo)
    _stop_on(runner, why)


def _stop_on(runner: NodeRunner, why: str) -> None:
    log.info("%s; shutting down", why)
    runner.stop()


async def _call_setup(setup: Setup, parameters: Any, runner: NodeRunner) -> List[Any]:
    result = setup(parameters, runner)
    if inspect.isawaitable(result):
        result = await result
    if result is None:
        return []
    if isinstance(result, asyncio.Future) or inspect.iscoroutine(result):
        return [result]
    return list(result)


def _init_logging() -> None:
    """Logs to stderr (the launcher pipes it), `PEPPY_LOG` setting the level."""
    level = os.environ.get("PEPPY_LOG", "INFO").upper()
    root = logging.getLogger()
    if not root.handlers:
        logging.basicConfig(
            stream=sys.stderr,
            level=getattr(logging, level, logging.INFO),
            format="%(asctime)s %(levelname)s %(name)s: %(message)s",
        )
    try:
        import zenoh

        zenoh.try_init_log_from_env()
    except Exception:
        pass
