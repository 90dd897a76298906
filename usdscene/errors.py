"""The one error hierarchy of usdscene.

Every error a user can cause derives from :class:`UsdSceneError`. An error carries one or
more :class:`Problem` records, each naming *where* (a JSON path such as
``openlabel.streams.cam_01.stream_properties.usdscene.fov_deg``, a USD prim path or a file)
and *what* (a sentence that quotes the bad value). Validators collect every problem first and
raise once, so a user fixes a document in one pass instead of one error per run.

The CLI prints ``usdscene: error: <where>: <message>`` per problem and exits with code 1.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Iterable


@dataclass(frozen=True)
class Problem:
    """One thing wrong with the input.

    Attributes:
        where: JSON path, USD prim path or file path of the offending value.
        message: human sentence that quotes the bad value and says what is expected.
    """

    where: str
    message: str

    def __str__(self) -> str:
        return f"{self.where}: {self.message}" if self.where else self.message


class UsdSceneError(Exception):
    """Base class of every error caused by user input or the environment (not by a bug)."""

    def __init__(self, problems: Iterable[Problem] | str, where: str = "") -> None:
        if isinstance(problems, str):
            problems = [Problem(where, problems)]
        self.problems: tuple[Problem, ...] = tuple(problems)
        super().__init__("\n".join(str(p) for p in self.problems))


class DocumentError(UsdSceneError):
    """The scene document (OpenLABEL/VCD JSON) is malformed or inconsistent."""


class AssetError(UsdSceneError):
    """An asset or the asset catalog is missing, unreadable or inconsistent."""


class CompositionError(UsdSceneError):
    """The scene cannot be composed into a USD stage (over-full place, cyclic relations...)."""


class RenderError(UsdSceneError):
    """Rendering failed or the requested render settings are impossible on this machine."""


class OutputError(UsdSceneError):
    """An output folder or file is unusable (escapes its root, not writable, inconsistent)."""


def usd_error_text(exc: BaseException) -> str:
    """The user-facing sentence of a USD error (``pxr.Tf.ErrorException``), on one line.

    USD's message lists every C++ frame as ``Error in 'function' at line N in file F : 'text'``;
    only the quoted texts help a user, so they are kept and joined with ``; ``.
    """
    texts = []
    for line in str(exc).splitlines():
        head, sep, text = line.rpartition(" : ")
        text = (text if sep else line).strip().strip("'").strip()
        if text and text not in texts:
            texts.append(text)
    return "; ".join(texts) or type(exc).__name__


class ProblemCollector:
    """Collects problems during validation and raises them together.

    Example:
        >>> problems = ProblemCollector()
        >>> problems.add("openlabel.frames.3", "frame number '3' is not in any interval")
        >>> problems.raise_if_any(DocumentError)
    """

    def __init__(self) -> None:
        self.problems: list[Problem] = []

    def add(self, where: str, message: str) -> None:
        """Record one problem at ``where`` (a JSON path, file or prim path)."""
        self.problems.append(Problem(where, message))

    def extend(self, problems: Iterable[Problem]) -> None:
        """Record several problems."""
        self.problems.extend(problems)

    def __bool__(self) -> bool:
        return bool(self.problems)

    def raise_if_any(self, error_type: type[UsdSceneError] = DocumentError) -> None:
        """Raise ``error_type`` with every recorded problem, if there is one."""
        if self.problems:
            raise error_type(self.problems)
