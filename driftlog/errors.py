"""Exceptions raised for bad input; each names the key or file, the value and what is allowed."""

__all__ = ["DriftlogError", "MeshError", "FlowFileError", "ScenarioError", "FlowDomainError",
           "InputFileError", "OutputPathError", "SizeError", "ArgumentError", "DriftlogWarning",
           "geographic_error"]


class DriftlogError(Exception):
    """Base class of driftlog's errors about user input."""


class MeshError(DriftlogError, ValueError):
    """A mesh that cannot be used (degenerate faces, bad connectivity, unreadable file)."""


class FlowFileError(DriftlogError, ValueError):
    """A flow file or hydro-model output that cannot be read (missing variable, NaN, bad times)."""


def geographic_error(where, what: str, value, error=FlowFileError) -> DriftlogError:
    """The error refusing a file whose coordinates are geographic (longitude/latitude, degrees).

    driftlog moves logs by velocity (m/s) x time: coordinates must be projected, in metres.
    ``what`` names the variable or attribute that says so, ``value`` its value (a long WKT
    is cut).  One wording for every reader (UGRID, CF grids, dfsu, rasters, HEC-RAS, sww).
    """
    text = " ".join(str(value).split())
    shown = text if len(text) <= 80 else text[:77] + "..."
    return error(f"{where}: {what} = {shown!r}: the coordinates are geographic (longitude/"
                 "latitude in degrees); driftlog needs projected coordinates in metres: "
                 "reproject the output (e.g. to its UTM zone) with the model's own tools or "
                 "with pyproj / GDAL, then read that")


class ScenarioError(DriftlogError, ValueError):
    """A scenario value that is not allowed; the message names the key, the value and the rule."""

    def __init__(self, key: str, value, allowed: str, source: str | None = None):
        self.key, self.value, self.allowed, self.source = key, value, allowed, source
        where = f"{source}: " if source else ""
        super().__init__(f"{where}[{key}] = {value!r}: {allowed}")


class FlowDomainError(DriftlogError, ValueError):
    """A request outside the flow's time span or domain."""


class InputFileError(DriftlogError, ValueError):
    """An input file of the wrong kind.

    A flow file where trajectories are expected, a directory, an empty, truncated, binary or
    non-UTF-8 file.
    """


class OutputPathError(DriftlogError, OSError):
    """An output path that cannot be written (parent is a file, read-only folder, the input)."""


class SizeError(DriftlogError, ValueError):
    """A run or a mesh too large for this machine's memory, estimated before allocating."""


class ArgumentError(DriftlogError, ValueError):
    """A bad argument of a public function or class (NaN, inf, negative, wrong shape)."""


class DriftlogWarning(UserWarning):
    """Something that lets a run start but that the user should know.

    E.g. a log overlapping an obstacle at its release; the CLI prints it as
    ``driftlog: warning: ...``.
    """
