"""The plugin manager: built-in plugins, entry points, blocking, the registry.

One function, :func:`get_plugin_manager`, builds it, in the order pytest and
tox use:

1. add the hook specifications (:mod:`seatkit.hookspecs`);
2. register the built-in plugins (``plugins/`` in the repository, listed in
   :data:`BUILTIN_PLUGINS`), always one way: imported by module name, as
   pytest imports its own plugins (they are packages of the ``seatkit``
   distribution, not entry points);
3. load every ``seatkit`` entry point (third-party plugins), unless
   ``SEATKIT_DISABLE_PLUGIN_AUTOLOAD`` is set;
4. ``check_pending()``: a plugin implementing a hook that does not exist is
   an error.

A plugin named in ``disabled`` (``--disable-plugin NAME``) is blocked with
:meth:`pluggy.PluginManager.set_blocked` before anything is loaded; a name
that is neither a built-in plugin nor an installed entry point is refused,
listing the names. A plugin that fails to import, or whose registration hook
raises, is reported by name (``Error importing plugin "foo": reason``) in
:attr:`SeatkitPluginManager.problems` and the rest keeps working; an unknown
component name then says what failed to load (a source tree that is not
installed cannot import the built-in plugins).

:class:`Registry` calls each registration hook of each plugin separately, so
it knows which plugin registered which component, and refuses a name
registered twice with an error naming both plugins. Once every component is
known it binds each template to the registered steps
(:meth:`seatkit.interfaces.SupportTemplate.bind`): a template whose steps
are unknown (for instance because their plugin is disabled) or misused is
left out, with its ``file:line`` problem reported. Every part of seatkit
finds components through the registry of the plugin manager it was given;
no module below the pipeline imports this one (a test checks it).
"""

from __future__ import annotations

import importlib
import importlib.metadata
import os
from pathlib import Path
from dataclasses import dataclass, field
from typing import Any, Iterable

import pluggy

from seatkit import hookspecs
from seatkit.errors import PluginError, RecipeError, SeatkitError
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

#: What an uninstalled checkout is told (once).
NOT_INSTALLED = (
    "seatkit's built-in plugins (packages of the seatkit distribution) cannot be imported: "
    "this checkout is not installed; run pip install -e . in it"
)

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
        self.disabled: tuple[str, ...] = ()
        #: a built-in plugin's module is missing: seatkit runs from a checkout that is not installed
        self.not_installed = False
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
    eps = _entry_points()
    known = sorted(set(BUILTIN_PLUGINS) | {ep.name for ep in eps})
    disabled = tuple(dict.fromkeys(disabled))
    for name in disabled:
        if name not in known:
            from seatkit.template.options import did_you_mean

            msg = f"--disable-plugin {name!r}: no such plugin{did_you_mean(name, known)}; the plugins are: {', '.join(known)}"
            raise PluginError(msg)
        pm.set_blocked(name)
    pm.disabled = disabled
    seatkit_version = ""
    try:
        seatkit_version = importlib.metadata.version("seatkit")
    except importlib.metadata.PackageNotFoundError:
        pass

    # 2. built-in plugins: imported by module name, through the same call as a third party's
    for name, module in BUILTIN_PLUGINS.items():
        _import_plugin(pm, name, lambda module=module: importlib.import_module(module), "seatkit", seatkit_version, builtin=True)
    if pm.not_installed:
        pm.problems.append(NOT_INSTALLED)

    # 3. third-party plugins: their entry points
    if autoload:
        for ep in eps:
            if ep.name not in pm.infos:
                _import_plugin(pm, ep.name, ep.load, *_dist_of(ep))

    # 4. hooks that do not exist are a plugin bug.
    try:
        pm.check_pending()
    except pluggy.PluginValidationError as e:
        raise PluginError(f"plugin {e.plugin!r} implements an unknown hook: {e}") from e
    return pm


def _import_plugin(pm: SeatkitPluginManager, name: str, load, distribution: str, version: str, *, builtin: bool = False) -> None:
    """Load one plugin and register it, unless it is blocked; a failure is a problem named after it."""
    if pm.is_blocked(name):
        return
    try:
        plugin = load()
        pm.register_plugin(plugin, name, distribution=distribution, version=version, builtin=builtin)
    except Exception as e:  # a broken plugin must not take the CLI down
        if builtin and isinstance(e, ModuleNotFoundError) and e.name == BUILTIN_PLUGINS.get(name):
            pm.not_installed = True
        pm.problems.append(f'Error importing plugin "{name}": {type(e).__name__}: {e}')


class Registry:
    """The components of every plugin, by kind and name.

    Built from the registration hooks; each hook implementation is called on
    its own so that a failing plugin is isolated and each component's plugin
    is known.
    """

    def __init__(self, pm: SeatkitPluginManager):
        self._pm = pm
        self._items: dict[str, dict[str, tuple[Any, str]]] = {kind: {} for kind in KIND_HOOKS}
        self._broken: dict[tuple[str, str], str] = {}
        self.pose_dirs: list[tuple[Path, str]] = []
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
        self._bind_templates()
        self._collect_pose_dirs()

    def _bind_templates(self) -> None:
        """Resolve every template's steps against the registered ones (see the module doc)."""
        steps = {n: c for n, (c, _) in self._items["template_step"].items()}
        hint = f" (disabled plugins: {', '.join(self._pm.disabled)})" if self._pm.disabled else ""
        for name, (template, plugin_name) in list(self._items["template"].items()):
            try:
                bound = template.bind(steps)
            except SeatkitError as e:
                message = f"{e}{hint}"
                self._pm.problems.append(f'template {name!r} of plugin "{plugin_name}" cannot be used: {message}')
                self._broken[("template", name)] = message
                del self._items["template"][name]
                info = self._pm.infos.get(plugin_name)
                if info is not None and name in info.components.get("template", []):
                    info.components["template"].remove(name)
                continue
            self._items["template"][name] = (bound, plugin_name)

    def _collect_pose_dirs(self) -> None:
        """Folders of pose files, each with its plugin, in registration order."""
        hook = self._pm.hook.seatkit_register_pose_dirs
        for impl in reversed(hook.get_hookimpls()):
            try:
                dirs = impl.function() or []
            except Exception as e:
                self._pm.problems.append(f'Error in plugin "{impl.plugin_name}" (seatkit_register_pose_dirs): {type(e).__name__}: {e}')
                continue
            for d in dirs:
                d = Path(d).resolve()
                if d not in {u for u, _ in self.pose_dirs}:
                    self.pose_dirs.append((d, impl.plugin_name))

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
            pass
        if (kind, name) in self._broken:
            raise RecipeError(f"{KIND_LABELS[kind]} {name!r} cannot be used: {self._broken[(kind, name)]}")
        from seatkit.template.options import did_you_mean

        have = ", ".join(self.names(kind)) or "none"
        msg = f"unknown {KIND_LABELS[kind]} {name!r}; available: {have}{did_you_mean(name, self.names(kind))}"
        if self._pm.disabled:
            msg += f" (disabled plugins: {', '.join(self._pm.disabled)})"
        failed = [p for p in self._pm.problems if p.startswith("Error importing")]
        if self._pm.not_installed:
            msg += f"; {NOT_INSTALLED} ({len(failed)} plugins failed to load, e.g. {failed[0]})"
        elif failed:
            msg += "; plugins that failed to load: " + "; ".join(failed)
        raise RecipeError(msg)

    def plugin_of(self, kind: str, name: str) -> str:
        """Name of the plugin that registered a component."""
        return self._items[kind][name][1]

    def items(self, kind: str) -> list[tuple[str, Any, str]]:
        """(name, component, plugin) of a kind, sorted by name."""
        return [(n, c, p) for n, (c, p) in sorted(self._items[kind].items())]
