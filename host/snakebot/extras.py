"""Optional dependencies: each serves one feature and is installed with an extra.

``pyproject.toml`` says which extra brings which package (``plot`` brings matplotlib);
this module reads that from the installed metadata, so a command whose extra is missing
fails with one line naming the ``pip install`` that fixes it, never an ImportError.
"""

from __future__ import annotations

import importlib.util
import re

from snakebot.errors import InputError

_EXTRA = re.compile(r"""extra\s*==\s*['"]([^'"]+)['"]""")
_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9._-]*")


class MissingExtraError(InputError):
    """A feature needs a package that is not installed."""


def available(module: str) -> bool:
    """Whether ``module`` can be imported."""
    return importlib.util.find_spec(module) is not None


def extra_for(package: str) -> str | None:
    """The extra of ``snakebot`` that installs ``package`` (None if none does)."""
    from importlib import metadata  # only to explain a missing package: not at start-up

    try:
        requirements = metadata.requires("snakebot") or []
    except metadata.PackageNotFoundError:
        return None
    key = package.lower().replace("_", "-")
    for requirement in requirements:
        name, extra = _NAME.match(requirement), _EXTRA.search(requirement)
        if name and extra and name.group().lower().replace("_", "-") == key:
            if extra.group(1) != "dev":  # dev pulls in the others; name the specific one
                return extra.group(1)
    return None


def install_hint(package: str, extra: str | None = None) -> str:
    """What to run to get ``package`` the way snakebot declares it (``extra`` names the
    extra when more than one brings the package)."""
    extra = extra or extra_for(package)
    return f"pip install 'snakebot[{extra}]'" if extra else f"pip install {package}"


def require(
    package: str, feature: str, extra: str | None = None, *, params: tuple[str, ...] = ()
) -> None:
    """Raise :class:`MissingExtraError` if ``package`` (also its module name) is missing;
    commands call it before they start work, so no result is lost to a missing package.
    ``params``: the parameters that ask for ``feature`` (the error is about them)."""
    if not available(package):
        raise MissingExtraError(
            f"{feature} needs {package}, which is not installed: {install_hint(package, extra)}"
        ).about(*params)
