"""The plugin manager: built-in plugins, entry points, blocking, the registry.

One function, :func:`get_plugin_manager`, builds it, in the order pytest and
tox use:

1. add the hook specifications (:mod:`seatkit.hookspecs`);
2. register the built-in plugins (``plugins/`` in the repository). They are
   declared as ``seatkit`` entry points of the ``seatkit`` distribution, and
   are loaded through those entry points exactly as a third-party plugin is;
   only when seatkit runs from a source tree without being installed are
   they imported by module name instead;
3. load every other ``seatkit`` entry point (third-party plugins), unless
   ``SEATKIT_DISABLE_PLUGIN_AUTOLOAD`` is set;
4. ``check_pending()``: a plugin implementing a hook that does not exist is
   an error.

A plugin named in ``disabled`` (``--disable-plugin NAME``) is blocked with
:meth:`pluggy.PluginManager.set_blocked` before anything is loaded. A plugin
that fails to import, or whose registration hook raises, is reported by name
(``Error importing plugin "foo": reason``) in :attr:`SeatkitPluginManager.problems`
and the rest keeps working.

:class:`Registry` calls each registration hook of each plugin separately, so
it knows which plugin registered which component, and refuses a name
registered twice with an error naming both plugins.
"""

from __future__ import annotations

import importlib
import importlib.metadata
import os
from dataclasses import dataclass, field
from typing import Any, Iterable

import pluggy

from seatkit import hookspecs
from seatkit.errors import PluginError, RecipeError
from seatkit.interfaces import COMPONENT_KINDS

ENTRY_POINT_GROUP = "seatkit"
AUTOLOAD_ENV = "SEATKIT_DISABLE_PLUGIN_AUTOLOAD"

#: Built-in plugins: entry-point name -> module (in ``plugins/``).
BUILTIN_PLUGINS: dict[str, str] = {
    "bodies": "seatkit_bodies",
    "qp": "seatkit_qp",
    "chair": "seatkit_chair",
    "bench": "seatkit_bench",
    "refiners": "seatkit_refiners",
    "exporters": "seatkit_exporters",
    "anny": "seatkit_anny",
}

#: Registration hook of each component kind.
KIND_HOOKS: dict[str, str] = {
    "body_model": "seatkit_register_body_models",
    "pressure_solver": "seatkit_register_pressure_solvers",
    "template": "seatkit_register_templates",
    "template_step": "seatkit_register_template_steps",
    "refiner": "seatkit_register_refiners",
    "exporter": "seatkit_register_exporters",
}

#: How each kind is called in messages.
KIND_LABELS: dict[str, str] = {
    "body_model": "body model",
    "pressure_solver": "pressure solver",
    "template": "template",
    "template_step": "template step",
    "refiner": "refiner",
    "exporter": "exporter",
}


@dataclass
class PluginInfo:
    """What ``seatkit plugins`` shows about one plugin."""

    name: str
    module: str
    distribution: str = ""
    version: str = ""
    builtin: bool = False
    components: dict[str, list[str]] = field(default_factory=dict)


class SeatkitPluginManager(pluggy.PluginManager):
    """A :class:`pluggy.PluginManager` that remembers plugin provenance and problems."""

    def __init__(self) -> None:
        super().__init__("seatkit")
        self.add_hookspecs(hookspecs)
        self.infos: dict[str, PluginInfo] = {}
        self.problems: list[str] = []
        self._registry: Registry | None = None

    def register_plugin(self, plugin: Any, name: str, *, distribution: str = "", version: str = "", builtin: bool = False) -> None:
        """Register ``plugin`` under ``name`` and record where it came from."""
        if self.is_blocked(name):
            return
        self.register(plugin, name=name)
        module = getattr(plugin, "__name__", type(plugin).__name__)
        self.infos[name] = PluginInfo(name, module, distribution, version, builtin)
        self._registry = None

    @property
    def registry(self) -> "Registry":
        """The merged components of every registered plugin (built lazily)."""
        if self._registry is None:
            self._registry = Registry(self)
        return self._registry


def _entry_points() -> list[importlib.metadata.EntryPoint]:
    return sorted(importlib.metadata.entry_points(group=ENTRY_POINT_GROUP), key=lambda ep: ep.name)


def _dist_of(ep) -> tuple[str, str]:
    dist = getattr(ep, "dist", None)
    if dist is None:
        return "", ""
    return dist.metadata["Name"] or "", dist.version or ""


def get_plugin_manager(*, disabled: Iterable[str] = (), autoload: bool | None = None) -> SeatkitPluginManager:
    """Build the plugin manager.

    Parameters
    ----------
    disabled : iterable of str
        Plugin names (entry-point names, e.g. ``chair``) to block.
    autoload : bool, optional
        Load third-party entry points; default: unless the environment
        variable ``SEATKIT_DISABLE_PLUGIN_AUTOLOAD`` is set to a non-empty
        value other than ``0``.

    Returns
    -------
    SeatkitPluginManager
    """
    if autoload is None:
        autoload = os.environ.get(AUTOLOAD_ENV, "") in ("", "0")
    pm = SeatkitPluginManager()
    for name in disabled:
        pm.set_blocked(name)

    eps = _entry_points()
    by_name = {ep.name: ep for ep in eps}
    seatkit_version = ""
    try:
        seatkit_version = importlib.metadata.version("seatkit")
    except importlib.metadata.PackageNotFoundError:
        pass

    # 2. built-in plugins, through their entry points when installed.
    for name, module in BUILTIN_PLUGINS.items():
        if pm.is_blocked(name):
            continue
        ep = by_name.get(name)
        try:
            if ep is not None and _dist_of(ep)[0] == "seatkit":
                plugin = ep.load()
                dist, version = _dist_of(ep)
            else:
                plugin = importlib.import_module(module)
                dist, version = "seatkit", seatkit_version
        except Exception as e:  # a broken built-in must not take the CLI down
            pm.problems.append(f'Error importing plugin "{name}": {type(e).__name__}: {e}')
            continue
        pm.register_plugin(plugin, name, distribution=dist, version=version, builtin=True)

    # 3. third-party plugins.
    if autoload:
        for ep in eps:
            if ep.name in pm.infos or pm.is_blocked(ep.name):
                continue
            dist, version = _dist_of(ep)
            if ep.name in BUILTIN_PLUGINS and dist == "seatkit":
                continue
            try:
                plugin = ep.load()
                pm.register_plugin(plugin, ep.name, distribution=dist, version=version)
            except Exception as e:
                pm.problems.append(f'Error importing plugin "{ep.name}": {type(e).__name__}: {e}')

    # 4. hooks that do not exist are a plugin bug.
    try:
        pm.check_pending()
    except pluggy.PluginValidationError as e:
        raise PluginError(f"plugin {e.plugin!r} implements an unknown hook: {e}") from e
    return pm


class Registry:
    """The components of every plugin, by kind and name.

    Built from the registration hooks; each hook implementation is called on
    its own so that a failing plugin is isolated and each component's plugin
    is known.
    """

    def __init__(self, pm: SeatkitPluginManager):
        self._pm = pm
        self._items: dict[str, dict[str, tuple[Any, str]]] = {kind: {} for kind in KIND_HOOKS}
        for kind, hook_name in KIND_HOOKS.items():
            hook = getattr(pm.hook, hook_name)
            # pluggy returns implementations last-registered first; keep registration order.
            for impl in reversed(hook.get_hookimpls()):
                plugin_name = impl.plugin_name
                try:
                    components = impl.function() or []
                except Exception as e:
                    pm.problems.append(f'Error in plugin "{plugin_name}" ({hook_name}): {type(e).__name__}: {e}')
                    continue
                for component in components:
                    self._add(kind, component, plugin_name)

    def _add(self, kind: str, component: Any, plugin_name: str) -> None:
        label = KIND_LABELS[kind]
        name = getattr(component, "name", None)
        if not isinstance(name, str) or not name:
            msg = f'plugin "{plugin_name}" registered a {label} without a name: {component!r}'
            raise PluginError(msg)
        protocol = COMPONENT_KINDS[kind]
        if not isinstance(component, protocol):
            msg = f'plugin "{plugin_name}" registered {label} {name!r} that does not implement {protocol.__name__}'
            raise PluginError(msg)
        if name in self._items[kind]:
            other = self._items[kind][name][1]
            msg = (
                f"{label} {name!r} is registered by two plugins: \"{other}\" and \"{plugin_name}\"; "
                f"disable one with --disable-plugin {plugin_name}"
            )
            raise PluginError(msg)
        self._items[kind][name] = (component, plugin_name)
        info = self._pm.infos.get(plugin_name)
        if info is not None:
            info.components.setdefault(kind, []).append(name)

    def names(self, kind: str) -> list[str]:
        """Registered names of a kind, sorted."""
        return sorted(self._items[kind])

    def get(self, kind: str, name: str) -> Any:
        """The component ``name`` of ``kind``.

        Raises
        ------
        RecipeError
            Naming the kind and the names that exist.
        """
        try:
            return self._items[kind][name][0]
        except KeyError:
            have = ", ".join(self.names(kind)) or "none"
            msg = f"unknown {KIND_LABELS[kind]} {name!r}; available: {have}"
            raise RecipeError(msg) from None

    def plugin_of(self, kind: str, name: str) -> str:
        """Name of the plugin that registered a component."""
        return self._items[kind][name][1]

    def items(self, kind: str) -> list[tuple[str, Any, str]]:
        """(name, component, plugin) of a kind, sorted by name."""
        return [(n, c, p) for n, (c, p) in sorted(self._items[kind].items())]
