"""Sweep files: a declared grid of runs, expanded into run specs with stable folder names.

A sweep file (YAML) names the grid and how to run it::

    methods: [egs, monogs]            # registered names or import paths module:attribute
    sequences: [demo, demo-fast]      # sequence folders or names under $EGS_BENCH_DATA
    seeds: [0, 1]                     # default [0]
    preset: cpu                       # one preset or a list (a grid axis); default paper
    device: cpu                       # cpu or cuda, or a list; default cpu
    max_frames: 10                    # optional: process only the first N frames
    set: {tracking_iters: 40}         # SLAM option overrides for every run (built-ins only)
    settings:                         # optional grid axis: named sets of overrides
      base: {}
      low-depth: {lambda_d: 0.05}
    protocol: egs                     # evaluation protocol applied after each run
    out: sweeps/demo                  # output folder (default sweeps/<file stem>)
    local: {jobs: auto, threads_per_job: auto, timeout_min: null}
    slurm: {partition: gpu, timeout_min: 240, gpus_per_node: 1, cpus_per_task: 8,
            mem_gb: 32, array_parallelism: 16, additional_parameters: {account: me}}

Runs go to ``<out>/runs/<sequence>/<method>[__<tag>]/seed<k>`` (the *run id* is the part after
``runs/``); the tag names the settings, preset or device when the sweep has several of them.
Each run has a configuration hash over everything that determines its result (method, the
sequence's ``meta.yaml`` + ``frames.csv``, seed, preset, device, frame limit, overrides and, for
built-in methods, the fully resolved SLAM configuration): a finished run with the same hash is
skipped when the sweep is started again, and one with a different hash is never silently reused.
"""

from __future__ import annotations

import hashlib
import json
import re
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, TypeVar

import yaml

from egs_bench.errors import ConfigError, InputError
from egs_bench.runs.locations import folder_name, relative_run_path, run_location

DEVICES = ("cpu", "cuda")
_KEYS = {"methods", "sequences", "seeds", "preset", "device", "max_frames", "set", "settings",
         "protocol", "out", "local", "slurm", "name"}
_LOCAL_KEYS = {"jobs", "threads_per_job", "cpu_budget", "timeout_min"}
_SLURM_KEYS = {"partition", "timeout_min", "gpus_per_node", "cpus_per_task", "mem_gb",
               "array_parallelism", "additional_parameters", "name"}


@dataclass(frozen=True)
class LocalOptions:
    """The local pool: ``jobs`` parallel runs (``None``: one per GPU when the runs use CUDA,
    else from the CPU budget), ``threads_per_job`` CPU threads each (``None``: the budget
    divided by the jobs), ``cpu_budget`` CPU threads in all (``None``: the CPUs this process may
    use), ``timeout_min`` per run (``None``: no limit)."""

    jobs: int | None = None
    threads_per_job: int | None = None
    cpu_budget: int | None = None
    timeout_min: float | None = None


@dataclass(frozen=True)
class SlurmOptions:
    """SLURM resources of each array task (submitit's parameter names without prefix)."""

    partition: str | None = None
    timeout_min: float = 240.0
    gpus_per_node: int = 0
    cpus_per_task: int = 4
    mem_gb: float | None = None
    array_parallelism: int = 16
    additional_parameters: dict[str, Any] = field(default_factory=dict)
    name: str = "egs-sweep"


@dataclass(frozen=True)
class SweepSpec:
    """A parsed sweep file (see the module docstring)."""

    path: Path | None
    methods: tuple[str, ...]
    sequences: tuple[str, ...]
    seeds: tuple[int, ...] = (0,)
    presets: tuple[str, ...] = ("paper",)
    devices: tuple[str, ...] = ("cpu",)
    max_frames: int | None = None
    options: dict[str, Any] = field(default_factory=dict)
    settings: dict[str, dict[str, Any]] = field(default_factory=lambda: {"": {}})
    protocol: str = "egs"
    out: Path = Path("sweeps/sweep")
    local: LocalOptions = LocalOptions()
    slurm: SlurmOptions = SlurmOptions()


@dataclass(frozen=True)
class RunSpec:
    """One run of a sweep: everything a worker process needs (plain data, JSON-serialisable).

    Attributes:
        run_id: ``<sequence>/<method>[__<tag>]/seed<k>``, stable across invocations.
        sweep_dir: the sweep's output folder (absolute).
        run_dir: the run folder (absolute), ``<sweep_dir>/runs/<run_id>``.
        method: method name or import path.
        sequence: the sequence folder (absolute).
        sequence_name: its name.
        seed, preset, device, max_frames: arguments of the method's ``run``.
        options: SLAM option overrides (the sweep's ``set`` merged with the settings').
        settings_name: name of the settings set (``None`` for the only, unnamed one).
        protocol: evaluation protocol run after the method.
        identity: what the configuration hash covers.
        config_hash: sha256 of ``identity`` (16 hex digits).
    """

    run_id: str
    sweep_dir: str
    run_dir: str
    method: str
    sequence: str
    sequence_name: str
    seed: int
    preset: str
    device: str
    max_frames: int | None
    options: dict[str, Any]
    settings_name: str | None
    protocol: str
    identity: dict[str, Any]
    config_hash: str

    def to_json(self) -> str:
        return json.dumps(asdict(self), indent=1, sort_keys=True) + "\n"

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> RunSpec:
        return cls(**{k: data[k] for k in cls.__dataclass_fields__})

    @property
    def key(self) -> str:
        """The run id as one file-name-safe component (locks, worker specs, logs)."""
        return self.run_id.replace("/", "--")


def _as_list(value: Any, what: str, where: Path | str, kind: type) -> list:
    items = value if isinstance(value, list) else [value]
    for item in items:
        if kind is int and (isinstance(item, bool) or not isinstance(item, int)):
            raise InputError(where, f"'{what}' must hold integers, found {item!r}")
        if kind is str and (not isinstance(item, str) or not item):
            raise InputError(where, f"'{what}' must hold non-empty strings, found {item!r}")
    if not items:
        raise InputError(where, f"'{what}' is empty")
    if len(set(map(str, items))) != len(items):
        raise InputError(where, f"'{what}' lists a value twice")
    return items


def _mapping(value: Any, what: str, where: Path | str) -> dict[str, Any]:
    if value is None:
        return {}
    if not isinstance(value, Mapping):
        raise InputError(where, f"'{what}' must be a mapping, found {type(value).__name__}")
    return dict(value)


_Options = TypeVar("_Options", "LocalOptions", "SlurmOptions")


def _sub_options(cls: type[_Options], data: Any, keys: set[str], what: str, where: Path | str
                 ) -> _Options:
    data = _mapping(data, what, where)
    unknown = sorted(set(data) - keys)
    if unknown:
        raise InputError(where, f"unknown key(s) in '{what}': {', '.join(unknown)} "
                                f"(known: {', '.join(sorted(keys))})")
    if "jobs" in data and data["jobs"] == "auto":
        data["jobs"] = None
    if "threads_per_job" in data and data["threads_per_job"] == "auto":
        data["threads_per_job"] = None
    for k in ("jobs", "threads_per_job", "cpu_budget", "gpus_per_node", "cpus_per_task",
              "array_parallelism"):
        v = data.get(k)
        if v is not None and (isinstance(v, bool) or not isinstance(v, int) or v < 0 or
                              (v == 0 and k != "gpus_per_node")):
            raise InputError(where, f"'{what}.{k}' must be a positive integer, found {v!r}")
    for k in ("timeout_min", "mem_gb"):
        v = data.get(k)
        if v is not None and (isinstance(v, bool) or not isinstance(v, int | float) or v <= 0):
            raise InputError(where, f"'{what}.{k}' must be a positive number, found {v!r}")
    if "additional_parameters" in data:
        data["additional_parameters"] = _mapping(data["additional_parameters"],
                                                 f"{what}.additional_parameters", where)
    return cls(**data)


def parse_sweep(data: Mapping[str, Any], where: Path | str = "<sweep>") -> SweepSpec:
    """Validate a sweep mapping (the YAML content) into a :class:`SweepSpec`.

    Raises:
        InputError: a missing, unknown or wrongly typed key (the message names ``where``).
    """
    if not isinstance(data, Mapping):
        raise InputError(where, "a sweep file must be a YAML mapping")
    unknown = sorted(set(data) - _KEYS)
    if unknown:
        raise InputError(where, f"unknown key(s): {', '.join(unknown)} "
                                f"(known: {', '.join(sorted(_KEYS))})")
    for key in ("methods", "sequences"):
        if key not in data:
            raise InputError(where, f"missing '{key}'")
    devices = _as_list(data.get("device", "cpu"), "device", where, str)
    for d in devices:
        if d not in DEVICES:
            raise InputError(where, f"'device' must be cpu or cuda, found {d!r}")
    max_frames = data.get("max_frames")
    if max_frames is not None and (isinstance(max_frames, bool) or not isinstance(max_frames, int)
                                   or max_frames < 1):
        raise InputError(where, f"'max_frames' must be a positive integer, found {max_frames!r}")
    raw_settings = data.get("settings")
    if raw_settings is None:
        settings: dict[str, dict[str, Any]] = {"": {}}
    elif isinstance(raw_settings, list):  # unnamed sets: named by their overrides
        settings = {}
        for item in raw_settings:
            item = _mapping(item, "settings", where)
            name = ",".join(f"{k}={v}" for k, v in sorted(item.items())) or "default"
            settings[name] = item
    else:
        settings = {str(k): _mapping(v, f"settings.{k}", where)
                    for k, v in _mapping(raw_settings, "settings", where).items()}
    if not settings:
        raise InputError(where, "'settings' is empty")
    protocol = data.get("protocol", "egs")
    from egs_bench.eval.protocols import get_protocol

    try:
        get_protocol(protocol)
    except ConfigError as exc:
        raise InputError(where, str(exc)) from None
    stem = Path(str(where)).stem if str(where) != "<sweep>" else "sweep"
    out = Path(str(data.get("out") or Path("sweeps") / stem))
    return SweepSpec(
        path=Path(where) if str(where) != "<sweep>" else None,
        methods=tuple(_as_list(data["methods"], "methods", where, str)),
        sequences=tuple(_as_list(data["sequences"], "sequences", where, str)),
        seeds=tuple(_as_list(data.get("seeds", [0]), "seeds", where, int)),
        presets=tuple(_as_list(data.get("preset", "paper"), "preset", where, str)),
        devices=tuple(devices),
        max_frames=max_frames,
        options=_mapping(data.get("set"), "set", where),
        settings=settings,
        protocol=protocol,
        out=out,
        local=_sub_options(LocalOptions, data.get("local"), _LOCAL_KEYS, "local", where),
        slurm=_sub_options(SlurmOptions, data.get("slurm"), _SLURM_KEYS, "slurm", where),
    )


def load_sweep(path: str | Path) -> SweepSpec:
    """Read and validate a sweep file.

    Raises:
        InputError: missing file, invalid YAML, or an invalid sweep (names the file).
    """
    path = Path(path)
    if not path.is_file():
        raise InputError(path, "sweep file not found")
    try:
        data = yaml.safe_load(path.read_text())
    except (yaml.YAMLError, UnicodeDecodeError) as exc:
        raise InputError(path, f"not valid YAML ({exc})") from None
    return parse_sweep(data, path)


def sequence_fingerprint(seq_dir: Path) -> str:
    """sha256 (16 hex digits) of a sequence's ``meta.yaml`` and ``frames.csv``: regenerated or
    different data gives another configuration hash."""
    h = hashlib.sha256()
    for name in ("meta.yaml", "frames.csv"):
        p = seq_dir / name
        h.update(name.encode())
        h.update(p.read_bytes() if p.is_file() else b"<missing>")
    return h.hexdigest()[:16]


def _method_name(method: str, where: Path | str) -> str:
    """The registered name of a method (import paths resolve to their object's ``name``)."""
    from egs_bench.runs.registry import get_method

    try:
        return get_method(method).name
    except ConfigError as exc:
        raise InputError(where, str(exc)) from None


def typed_options(options: Mapping[str, Any], method: object = None) -> dict[str, Any]:
    """A sweep's ``set``/``settings`` values typed by the rules of ``egs-bench run --set``
    (:func:`egs_bench.slam.methods.parse_method_options`: ``1e-3``, which YAML 1.1 reads as a
    string, is a number where the field takes one; ``method``'s components' own fields are
    options too), keyed by ``group.field``.

    Raises:
        ConfigError: an unknown option or a value of the wrong type.
    """
    from egs_bench.slam.methods import parse_method_options

    return parse_method_options(method, [f"{k}={json.dumps(v)}" for k, v in options.items()])


def command_line_options(spec: SweepSpec, items: Sequence[str]) -> dict[str, Any]:
    """``egs-bench sweep --set`` items, parsed by the rules of ``egs-bench run --set``
    (:func:`egs_bench.slam.methods.parse_method_options`) against the groups of the sweep's
    methods: a field that one method's components add (``keyframes.n``) is an option, as in
    the file's ``set``, and each run then checks it against its own method (:func:`expand`).

    Raises:
        ConfigError: an item that no method of the sweep takes (the message for the first
            method), or a value of the wrong type.
    """
    from egs_bench.runs.registry import get_method
    from egs_bench.slam.methods import parse_method_options

    found: list[object] = []
    for method in spec.methods:
        try:
            found.append(get_method(method))
        except ConfigError:
            continue  # expand() names the sweep file with this error
    out: dict[str, Any] = {}
    for item in items:
        first: ConfigError | None = None
        for candidate in found or [None]:
            try:
                out.update(parse_method_options(candidate, [item]))
                break
            except ConfigError as exc:
                first = first or exc
        else:
            assert first is not None
            raise first
    return out


def _resolved_config(method: str, preset: str, options: Mapping[str, Any],
                     where: Path | str, meta: Mapping[str, Any] | None = None
                     ) -> dict[str, Any] | None:
    """The fully resolved SLAM configuration of a built-in method on a sequence with ``meta``
    (what its run writes to ``config.yaml``), ``None`` for plugins."""
    from egs_bench.runs.registry import get_method
    from egs_bench.slam.methods import ConfiguredSlamMethod

    m = get_method(method)
    if not isinstance(m, ConfiguredSlamMethod):
        if options:
            raise InputError(where, f"'set'/'settings' override SLAM options of built-in "
                                    f"methods; {method!r} is a user method")
        return None
    try:  # the same typing rules as `egs-bench run --set`
        typed = typed_options(options, m)
        return m.config(preset, dict(meta or {})).replace(**typed).validate().to_dict()
    except ConfigError as exc:
        raise InputError(where, f"{method} with preset {preset!r}: {exc}") from None


def _tag(parts: Sequence[str]) -> str:
    text = folder_name("__".join(p for p in parts if p))
    if len(text) > 60:
        text = text[:48] + "-" + hashlib.sha256(text.encode()).hexdigest()[:8]
    return text


def expand(spec: SweepSpec, sequences: Mapping[str, Path], out: Path | None = None,
           extra_options: Mapping[str, Any] | None = None) -> list[RunSpec]:
    """All runs of ``spec`` in a stable order (sequence, method, settings, preset, device, seed).

    Args:
        sequences: each entry of ``spec.sequences`` -> its resolved sequence folder.
        out: the sweep's output folder (default ``spec.out``).
        extra_options: overrides for every run on top of the file's ``set`` (``--set``).

    Raises:
        InputError: an unknown method or an invalid override (names the sweep file).
    """
    from egs_bench.datasets.sequence import Sequence as SeqReader

    where: Path | str = spec.path or "<sweep>"
    out = (out or spec.out).resolve()
    base_options = {**spec.options, **(extra_options or {})}
    named_settings = len(spec.settings) > 1 or "" not in spec.settings
    runs: list[RunSpec] = []
    seen: set[str] = set()
    for entry in spec.sequences:
        seq_dir = Path(sequences[entry]).resolve()
        seq = SeqReader.open(seq_dir, check_images=False)
        seq_name = seq.name
        fingerprint = sequence_fingerprint(seq_dir)
        for method in spec.methods:
            mname = _method_name(method, where)
            for sname, soptions in spec.settings.items():
                options = {**base_options, **soptions}
                for preset in spec.presets:
                    resolved = _resolved_config(method, preset, options, where, seq.meta)
                    for device in spec.devices:
                        tag = _tag([sname if named_settings else "",
                                    preset if len(spec.presets) > 1 else "",
                                    device if len(spec.devices) > 1 else ""])
                        for seed in spec.seeds:
                            run_id = relative_run_path(seq_name, mname, variant=tag,
                                                       seed=seed)
                            if run_id in seen:
                                raise InputError(where, f"two runs map to the folder {run_id!r}"
                                                        " (the same sequence listed twice?)")
                            seen.add(run_id)
                            identity = {"method": method,
                                        "sequence": {"name": seq_name,
                                                     "fingerprint": fingerprint},
                                        "seed": seed, "preset": preset, "device": device,
                                        "max_frames": spec.max_frames, "options": options,
                                        "resolved": resolved}
                            digest = hashlib.sha256(json.dumps(
                                identity, sort_keys=True, default=str).encode()).hexdigest()
                            runs.append(RunSpec(
                                run_id=run_id, sweep_dir=str(out),
                                run_dir=str(run_location(out, seq_name, mname,
                                                         variant=tag, seed=seed)),
                                method=method,
                                sequence=str(seq_dir), sequence_name=seq_name, seed=seed,
                                preset=preset, device=device, max_frames=spec.max_frames,
                                options=options,
                                settings_name=sname if named_settings else None,
                                protocol=spec.protocol, identity=identity,
                                config_hash=digest[:16]))
    return runs


def parse_shard(text: str | None) -> tuple[int, int] | None:
    """``"i/N"`` -> ``(i, N)`` with ``0 <= i < N``; ``None`` stays ``None``."""
    if text is None:
        return None
    m = re.fullmatch(r"\s*(\d+)\s*/\s*(\d+)\s*", text)
    if not m or int(m.group(2)) < 1 or int(m.group(1)) >= int(m.group(2)):
        raise ConfigError(f"--shard must be i/N with 0 <= i < N (e.g. 0/4), got {text!r}")
    return int(m.group(1)), int(m.group(2))


def in_shard(run: RunSpec, shard: tuple[int, int] | None) -> bool:
    """Whether ``run`` belongs to ``shard`` (a stable hash of the run id, modulo N)."""
    if shard is None:
        return True
    i, n = shard
    return int(hashlib.sha256(run.run_id.encode()).hexdigest(), 16) % n == i
