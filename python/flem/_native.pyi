"""Type stubs of the extension module ``flem._native`` (python/src/lib.rs). The public API is
``flem`` itself (``flem/__init__.py``); these functions take a scene as (TOML text, path for
messages, base folder for relative paths)."""
from typing import Any, Callable, Dict, List, Optional, Tuple

__version__: str

def scene_check(text: str, path: str, base: str) -> None:
    """Validates scene text as ``flem check`` would; raises ``flem.SceneError``."""

def scene_set(text: str, path: str, base: str, key: str, value_json: str) -> str:
    """The scene text with ``key`` (a key path) set to a JSON value, validated."""

def scene_from_json(json: str, path: str, base: str) -> str:
    """TOML text of a scene given as JSON, validated."""

def scene_to_json(text: str) -> str: ...
def scene_resolved(text: str, path: str, base: str) -> str: ...
def run(
    text: str,
    path: str,
    base: str,
    out: str,
    threads: Optional[int] = None,
    resume: Optional[str] = None,
    on_stage: Optional[Callable[[Dict[str, Any]], None]] = None,
    on_progress: Optional[Callable[[Dict[str, Any]], None]] = None,
    progress_every: float = 0.2,
) -> Dict[str, Any]:
    """Runs a scene into ``out`` with the GIL released: ``{"arrays": {...}, "compare": json,
    "warnings": [...], "checkpoint": path or None}``. Raises SceneError, FlemError,
    RunInterrupted (Ctrl-C, checkpoint written) or a callback's exception."""

def compare(text: str, path: str, base: str, out: str) -> str:
    """``flem compare`` into ``out``: the rows of compare.json as JSON text."""

def run_task(task: int, text: str, path: str, base: str, params_json: str, out: str, threads: Optional[int] = 1) -> str:
    """One sweep task (as ``flem sweep``): its row as JSON; a failure is the row's ``error``."""

def plugins() -> List[Tuple[str, str, Optional[str]]]: ...
def allow_plugins(yes: bool) -> None: ...
