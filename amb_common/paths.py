"""Where the package's data files are: the colcon install space, else this source tree."""

from __future__ import annotations

from pathlib import Path

PACKAGE = "amb_wavelet_control"
SOURCE_ROOT = Path(__file__).resolve().parent.parent


def config_file(name: str | Path) -> Path:
    """Return ``config/<name>`` of the package (installed share folder, else the source tree).

    Parameters
    ----------
    name : str or pathlib.Path
        Path relative to ``config/``, e.g. ``rig.yaml`` or ``scenarios/x.yaml``.

    Returns
    -------
    pathlib.Path
        The installed copy if the package is on the ament index and has the file, else the
        source tree's path (which may not exist; callers report that).
    """
    try:
        from ament_index_python.packages import get_package_share_directory

        installed = Path(get_package_share_directory(PACKAGE)) / "config" / name
        if installed.is_file():
            return installed
    except (ImportError, LookupError, ValueError):
        pass
    return SOURCE_ROOT / "config" / name


def scenario_file(name: str | Path) -> Path:
    """
    Return the scenario file ``name``: a path, else a name in the package's ``config/scenarios``.

    Raises
    ------
    FileNotFoundError
        If neither exists.
    """
    path = Path(name)
    if path.is_file():
        return path.resolve()
    path = config_file(Path("scenarios") / name)
    if not path.is_file():
        raise FileNotFoundError(f"scenario {str(name)!r} not found (nor in config/scenarios)")
    return path.resolve()
