"""seatkit's exceptions.

There is one base class, :class:`SeatkitError`, that plugins may raise too.
A ``SeatkitError`` is a *user* error: the CLI prints its message as one line
on stderr and exits non-zero; any other exception is a bug and shows a
traceback (with ``--debug`` a user error shows one as well).

Messages name the offending file, field and value::

    msg = f"{path}:{line}: faces[4].segment: unknown segment 'Thigh'; expected one of ..."
    raise RecipeError(msg)
"""

from __future__ import annotations

from seatkit.messages import MAX_MESSAGE, format_path, one_line


class SeatkitError(Exception):
    """Base class of every error seatkit reports to a user.

    A text message is put on one line of at most :data:`~seatkit.messages.MAX_MESSAGE`
    characters when the error is made (:func:`seatkit.messages.one_line`
    summarises a longer one, keeping its start and end), so that every
    refusal prints as one bounded line wherever it is shown.
    """

    def __init__(self, *args):
        if args and isinstance(args[0], str) and (len(args[0]) > MAX_MESSAGE or "\n" in args[0] or "\r" in args[0]):
            args = (one_line(args[0]),) + args[1:]
        super().__init__(*args)


class RecipeError(SeatkitError):
    """A recipe, template or pose YAML file is malformed or names unknown things."""


class ParamError(RecipeError):
    """A component's parameter is wrong; the caller knows where the parameters came from.

    Components (templates, refiners) check their parameters without knowing
    the file: ``path`` is the key path inside the parameters
    (``("steps", "border", "width")``), ``problem`` what was expected. The
    recipe checker re-raises it as ``recipe.yaml:12: template_params.steps.border.width: ...``.
    """

    def __init__(self, path, problem: str):
        self.path = tuple(path)
        self.problem = problem
        super().__init__(f"{format_path(self.path)}: {problem}")

    def __reduce__(self):
        return (type(self), (self.path, self.problem))


class StructureError(SeatkitError):
    """The shell cannot be analysed as asked (bad thickness, no floor contact, ...); ``seatkit.structure.StructureError``."""


class InputError(SeatkitError):
    """An input file (mesh, BVH, glTF, cage) is unreadable or invalid."""


class PluginError(SeatkitError):
    """A plugin failed to load, or two plugins registered the same component name."""


class UnsupportedPoseError(SeatkitError):
    """The method cannot support this pose (the paper's Section 6 limitations).

    Attributes
    ----------
    parts : list of str
        The body segments (or people) that cannot be supported.
    diagnostics : dict
        What could be supported, for saving next to the output.
    """

    def __init__(self, message: str, *, parts=(), diagnostics=None):
        super().__init__(message)
        self.parts = list(parts)
        self.diagnostics = dict(diagnostics or {})


class InfeasibleSupportError(SeatkitError):
    """The contact set cannot hold the body in equilibrium."""


class SolverError(SeatkitError):
    """A numerical solver failed or returned an answer that violates its constraints."""


class MissingExtraError(SeatkitError):
    """An optional dependency is needed: the message names the pip extra.

    ``first`` is a command that must run before the extra is installed (the
    anny extra needs ``pip install torch==2.13.0`` first), named in the
    message.
    """

    def __init__(self, package: str, extra: str, first: str | None = None):
        install = f"pip install 'seatkit[{extra}]'"
        how = f"{first} first, then {install}" if first else install
        super().__init__(f"this feature needs the optional package '{package}': install it with {how}")
        self.package = package
        self.extra = extra
        self.first = first

    def __reduce__(self):
        # rebuilt from its own arguments, so that it survives pickling (a
        # helper process of seatkit.workers, a Dask worker)
        return (type(self), (self.package, self.extra, self.first))
