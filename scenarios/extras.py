"""The optional extras: a module that only some commands need, imported when one of them runs.

The core install runs every scenario with every feedback source; the rest comes with an extra
(``pip install 'offtrack[cluster]'``, ``[tune]``, ``[ros]``, ``[opendrive]``, ``[rl]``, ``[bench]`` or ``[all]``).
:func:`require` imports such a module and, when it is missing, raises the project's input error naming the pip line,
which the CLI prints as one line with exit code 2.
"""

from __future__ import annotations

import importlib
from types import ModuleType

from vehicle_model.errors import InputError

DISTRIBUTIONS = {
    "distributed": "dask",
    "rosbags.image": "rosbags-image",
    "stable_baselines3": "stable-baselines3",
}
"""The package that provides an optional module where its name is not the module's, as the error says it
(``distributed`` comes with ``dask``)."""


def require(module: str, extra: str, purpose: str) -> ModuleType:
    """Import an optional module, or say which extra to install.

    Parameters
    ----------
    module
        The module's import name (``"distributed"``, ``"rosbags.image"``).
    extra
        The offtrack extra that installs it (``"cluster"``, ``"ros"``).
    purpose
        What needs it, as the message's subject (``"offtrack study --scheduler"``).

    Returns
    -------
    ModuleType
        The imported module.

    Raises
    ------
    vehicle_model.errors.InputError
        The module cannot be imported: ``"{purpose} needs {package}: pip install 'offtrack[{extra}]'"``.
    """
    try:
        return importlib.import_module(module)
    except ImportError:
        package = DISTRIBUTIONS.get(module, module)
        raise InputError(f"{purpose} needs {package}: pip install 'offtrack[{extra}]'") from None
