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
listing the names.

A broken plugin never takes the rest down (pytest's and pluggy's rule). It is
reported in :attr:`SeatkitPluginManager.problems` (one line each, shown as a
warning by every command and listed by ``seatkit plugins``) and left out:

* a plugin that fails to import: ``Error importing plugin "foo": reason``
  (an uninstalled source tree cannot import the built-in plugins: an
  unknown component then says so);
* a plugin that implements a hook that does not exist, whose registration
  hook raises (a template YAML error: its ``file:line``), that registers a
  component without a name, lacking a member of its interface (named), with
  options that are not :class:`seatkit.options.Option`, or under a name
  another plugin registered first: ``plugin "foo" is disabled: reason``.
  Every component of that plugin is left out, it is unregistered, and a
  recipe naming one of them is told why.

:class:`Registry` calls each registration hook of each plugin separately, so
it knows which plugin registered which component. Once every component is
known it binds each template to the registered steps
(:meth:`seatkit.interfaces.SupportTemplate.bind`): a template whose steps
are unknown (for instance because their plugin is disabled) or misused is
left out, with its ``file:line`` problem reported. The steps a template is
bound to, and the refiners and exporters a build runs
(:meth:`Registry.guarded`), are wrapped in :class:`Guarded`: a bug in one
(any exception that is not a :class:`~seatkit.errors.SeatkitError` or an
``OSError``) becomes one :class:`~seatkit.errors.PluginError` line naming
the component, its plugin and the template file, chained to the original
exception (``seatkit --debug`` shows its traceback). Every part of seatkit
finds components through the registry of the plugin manager it was given;
no module below the pipeline imports this one (a test checks it).
"""

from __future__ import annotations

import functools
import importlib
import importlib.metadata
import os
from collections.abc import Mapping
from pathlib import Path
from dataclasses import dataclass, field
from typing import Any, Iterable

import pluggy

from seatkit import hookspecs
from seatkit.errors import PluginError, RecipeError, SeatkitError
from seatkit.interfaces import COMPONENT_KINDS
from seatkit.messages import clip
from seatkit.options import Option

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


#: Longest reason quoted in a problem line, characters (a line stays under 500).
MAX_REASON = 400


@dataclass
class PluginInfo:
    """What ``seatkit plugins`` shows about one plugin."""

    name: str
    module: str
    distribution: str = ""
    version: str = ""
    builtin: bool = False
    components: dict[str, list[str]] = field(default_factory=dict)
    #: why the plugin was disabled while its components were registered ("" when it works)
    disabled: str = ""


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

    def disable_plugin(self, name: str, reason: str) -> None:
        """Unregister plugin ``name`` that failed to register, keeping why (one problem line)."""
        self.problems.append(f'plugin "{name}" is disabled: {clip(reason, MAX_REASON)}')
        if self.get_plugin(name) is not None:
            self.unregister(name=name)
        info = self.infos.get(name)
        if info is not None:
            info.disabled = clip(reason, MAX_REASON)
            info.components = {}

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

    # 4. hooks that do not exist are a plugin bug: that plugin is disabled, the rest kept
    while True:
        try:
            pm.check_pending()
        except pluggy.PluginValidationError as e:
            name = pm.get_name(e.plugin) or repr(e.plugin)
            pm.disable_plugin(name, _unknown_hooks(pm, e.plugin) or str(e))
            continue
        break
    return pm


def _unknown_hooks(pm: SeatkitPluginManager, plugin: Any) -> str:
    """``it implements an unknown hook 'x' (did you mean 'y'?)`` for a plugin's hooks that are not seatkit's."""
    from seatkit.options import did_you_mean

    specs = [n for n in dir(hookspecs) if n.startswith("seatkit_")]
    unknown = [c.name for c in pm.get_hookcallers(plugin) or () if not c.has_spec()]
    return "; ".join(f"it implements an unknown hook {n!r}{did_you_mean(n, specs)}" for n in unknown)


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
        pm.problems.append(f'Error importing plugin "{name}": {type(e).__name__}: {clip(str(e), MAX_REASON)}')


class Registry:
    """The components of every plugin, by kind and name.

    Built from the registration hooks; each hook implementation is called on
    its own so that a failing plugin is isolated and each component's plugin
    is known. A plugin whose components cannot all be registered is disabled
    as a whole (see the module doc), in registration order: of two plugins
    registering one name, the later one.
    """

    def __init__(self, pm: SeatkitPluginManager):
        self._pm = pm
        self._items: dict[str, dict[str, tuple[Any, str]]] = {kind: {} for kind in KIND_HOOKS}
        self._broken: dict[tuple[str, str], str] = {}
        self.pose_dirs: list[tuple[Path, str]] = []
        offered: dict[str, dict[str, list]] = {}  # plugin -> kind -> its components
        failed: dict[str, str] = {}
        for kind, hook_name in KIND_HOOKS.items():
            hook = getattr(pm.hook, hook_name)
            for impl in hook.get_hookimpls():
                plugin_name = impl.plugin_name
                if plugin_name in failed:
                    continue
                try:
                    components = list(impl.function() or [])
                    problem = next(filter(None, (_component_problem(kind, c) for c in components)), None)
                except SeatkitError as e:  # a template YAML error: its file:line
                    problem = f"its {hook_name} raised: {e}"
                except Exception as e:
                    problem = f"its {hook_name} raised {type(e).__name__}: {e}"
                if problem is not None:
                    failed[plugin_name] = problem
                    continue
                offered.setdefault(plugin_name, {})[kind] = components
        # merged plugin by plugin, in registration order (built-ins first)
        for plugin_name, _ in pm.list_name_plugin():
            if plugin_name in failed or plugin_name not in offered:
                continue
            clash = self._clash(offered[plugin_name], plugin_name)
            if clash is not None:
                failed[plugin_name] = clash
                continue
            for kind, components in offered[plugin_name].items():
                for component in components:
                    self._add(kind, component, plugin_name)
        for plugin_name, reason in failed.items():
            pm.disable_plugin(plugin_name, reason)
        self._failed = failed
        self._bind_templates()
        self._collect_pose_dirs()

    def _clash(self, components: dict[str, list], plugin_name: str) -> str | None:
        """Why ``plugin_name``'s components cannot join (a name taken), or None."""
        for kind, items in components.items():
            label = KIND_LABELS[kind]
            seen: set[str] = set()
            for component in items:
                name = component.name
                if name in seen:
                    return f"it registers {label} {name!r} twice"
                seen.add(name)
                if name in self._items[kind]:
                    other = self._items[kind][name][1]
                    return (
                        f"its {label} {name!r} is registered by two plugins: \"{other}\" and \"{plugin_name}\"; "
                        f"rename it, or switch the other off with --disable-plugin {other}"
                    )
        return None

    def _bind_templates(self) -> None:
        """Resolve every template's steps against the registered ones (see the module doc)."""
        hint = f" (disabled plugins: {', '.join(self._pm.disabled)})" if self._pm.disabled else ""
        for name, (template, plugin_name) in list(self._items["template"].items()):
            where = template_label(template)
            steps = {n: Guarded(c, KIND_LABELS["template_step"], p, where=where) for n, (c, p) in self._items["template_step"].items()}
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
        self._items[kind][component.name] = (component, plugin_name)
        info = self._pm.infos.get(plugin_name)
        if info is not None:
            info.components.setdefault(kind, []).append(component.name)

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
        failed = [p for p in self._pm.problems if p.startswith(("Error importing", "plugin "))]
        if self._pm.not_installed:
            msg += f"; {NOT_INSTALLED} ({len(failed)} plugins failed to load, e.g. {failed[0]})"
        elif failed:
            msg += "; plugins that failed to load: " + "; ".join(failed)
        raise RecipeError(msg)

    def guarded(self, kind: str, name: str, *, template: Any = None, keywords: Mapping[str, dict] | None = None) -> "Guarded":
        """The component ``name`` of ``kind`` (:meth:`get`), wrapped in :class:`Guarded`.

        ``template`` is the template of the build it serves, named (with its
        file) in the message of a bug; ``keywords`` as :class:`Guarded`'s.
        """
        component = self.get(kind, name)
        return Guarded(component, KIND_LABELS[kind], self.plugin_of(kind, name), where=template_label(template), keywords=keywords)

    def plugin_of(self, kind: str, name: str) -> str:
        """Name of the plugin that registered a component."""
        return self._items[kind][name][1]

    def items(self, kind: str) -> list[tuple[str, Any, str]]:
        """(name, component, plugin) of a kind, sorted by name."""
        return [(n, c, p) for n, (c, p) in sorted(self._items[kind].items())]


def protocol_members(protocol: type) -> list[str]:
    """The attributes and methods a component of ``protocol`` must have, sorted."""
    members = set(getattr(protocol, "__annotations__", {}))
    members |= {n for n, v in vars(protocol).items() if callable(v) and not n.startswith("_")}
    return sorted(members)


def _component_problem(kind: str, component: Any) -> str | None:
    """Why ``component`` cannot be registered as a ``kind``, or None: its name, members and options."""
    label = KIND_LABELS[kind]
    name = getattr(component, "name", None)
    if not isinstance(name, str) or not name.strip():
        return f"it registers a {label} without a name (a non-empty str): {clip(repr(component), 80)}"
    protocol = COMPONENT_KINDS[kind]
    if not isinstance(component, protocol):
        members = protocol_members(protocol)
        missing = [m for m in members if not hasattr(component, m)]
        what = f"has no {', '.join(repr(m) for m in missing)}" if missing else "does not match it"
        return f"its {label} {name!r} does not implement {protocol.__name__}: it {what} (a {protocol.__name__} has {', '.join(members)})"
    options = getattr(component, "options", None)
    if options is not None:
        if not isinstance(options, Mapping):
            return f"its {label} {name!r} declares options {clip(repr(options), 60)}; expected a mapping of option names to seatkit.options.Option"
        for key, opt in options.items():
            if not isinstance(opt, Option):
                return f"its {label} {name!r} declares option {key!r} as {clip(repr(opt), 60)}; expected a seatkit.options.Option"
    return None


def template_label(template: Any) -> str:
    """``template 'chair' (path/chair.yaml)``: how a bug's message names the template of a build."""
    if template is None:
        return ""
    source = getattr(getattr(template, "spec", None), "source", None)
    return f"template {template.name!r}" + (f" ({source})" if source else "")


class Guarded:
    """A component whose methods turn a bug into one :class:`~seatkit.errors.PluginError` line.

    Reads as the component it wraps (every attribute is the component's; it
    pickles with it). A method that raises anything but a
    :class:`~seatkit.errors.SeatkitError` (a user's or a component's own
    refusal, passed on unchanged) or an ``OSError`` (a full disk: the
    output's business) raises ``PluginError('refiner 'x' of plugin "p"
    failed on template 't' (file): ValueError: ...')`` from it.
    ``keywords`` (``{method name: {keyword: value}}``) are added to those
    methods' calls: an exporter's checked ``options``.
    """

    def __init__(self, component: Any, label: str, plugin: str, *, where: str = "", keywords: Mapping[str, dict] | None = None):
        self.__dict__.update(_component=component, _label=label, _plugin=plugin, _where=where, _keywords=dict(keywords or {}))

    def __repr__(self) -> str:
        return f"Guarded({self._component!r})"

    @property
    def component_label(self) -> str:
        """``refiner 'x' of plugin "p"``: how messages name the component."""
        return f'{self._label} {self._component.name!r} of plugin "{self._plugin}"'

    def __getattr__(self, name: str) -> Any:
        if name.startswith("_"):
            raise AttributeError(name)
        value = getattr(self._component, name)
        if not callable(value) or isinstance(value, type):
            return value
        return functools.partial(self._call, value)

    def _call(self, method, *args, **kwargs):
        kwargs = {**self._keywords.get(method.__name__, {}), **kwargs}
        try:
            return method(*args, **kwargs)
        except (SeatkitError, OSError):
            raise
        except Exception as e:
            raise PluginError(self.describe(method.__name__, e)) from e

    def describe(self, method: str, error: BaseException) -> str:
        """The one line of a bug ``error`` raised by ``method``."""
        where = f" on {self._where}" if self._where else ""
        return (
            f"{self.component_label} failed{where} in {method}(): "
            f"{type(error).__name__}: {clip(str(error), 200)} (a bug in the plugin; seatkit --debug shows the traceback)"
        )
