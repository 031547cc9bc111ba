"""Docs that cannot rot: every repository path the guides name exists, and every ``semdp-*``
command they show composes.

The pages (``docs/``), the README, the package READMEs, ``outputs/reference/README.md`` and
CONTRIBUTING.md are scanned:

* **paths**: a word in a code span, a fenced block or a link target that starts with one of the
  repository's top-level folders (``semdp/``, ``conf/``, ``outputs/``, ...) must exist. Words
  with a placeholder (``<run dir>``, ``{a,b}``, ``*``, ``$PWD``) and gymnasium ids
  (``sims/SafetyPointPush1-v0``) are not paths; ``outputs/`` other than ``outputs/reference/``
  is where the apps write, so only ``outputs/reference/`` must be committed. A page's
  ``figures/<path>`` link names ``outputs/reference/<path>`` (docs/hooks/reference_figures.py).
* **commands**: each ``semdp-*`` command of a fenced block is checked the cheap way its app
  allows, in this process: ``semdp-train``, ``semdp-plan`` and ``semdp-toy`` compose their Hydra
  config with the shown overrides (as ``--cfg job`` would; every value of a sweep ``a,b``,
  ``range(...)`` or of the guides' ``a|b`` once; ``<placeholder>`` as a word) and
  ``semdp-train``'s overrides are type-checked
  as the app does; a Ray sweep must name its ``hydra.sweep.dir`` (conf/hydra/launcher/
  cluster_ray.yaml); ``semdp-eval zoo:<name>`` needs the zoo entry and known settings;
  ``semdp-bench`` a known suite and, where it declares them, known keys; ``semdp-report`` its
  options.

The planted tests at the end prove that each check can fail.
"""

from __future__ import annotations

import re
import shlex
from collections.abc import Iterator
from pathlib import Path

import pytest
from hydra.core.override_parser.overrides_parser import OverridesParser
from omegaconf import OmegaConf

from semdp.configs import compose_config
from semdp.paths import CONF_DIR

ROOT = Path(__file__).resolve().parents[1]
REFERENCE = ROOT / "outputs" / "reference"
#: The files whose paths and commands are checked.
DOC_FILES = sorted(
    [*(ROOT / "docs").rglob("*.md"), ROOT / "semdp" / "README.md", ROOT / "solvers" / "README.md",
     ROOT / "sims" / "README.md", ROOT / "CONTRIBUTING.md", ROOT / "README.md",
     ROOT / "outputs" / "reference" / "README.md"]
)
TOP_FOLDERS = ("semdp", "solvers", "sims", "conf", "tests", "outputs", "docs", "examples")
PATH_WORD = re.compile(
    r"(?:^|(?<=[\s=(\[\"'`]))((?:" + "|".join(TOP_FOLDERS) + r")/[^\s`'\"),;\]]*)"
)
GYM_ID = re.compile(r"^(?:sims|semdp)/[A-Z]\w*-v\d+$")
PLACEHOLDER_CHARS = set("<>{}*$…")
FENCE = re.compile(r"^```[^\n]*\n(.*?)^```", re.S | re.M)
CODE_SPAN = re.compile(r"`([^`\n]+)`")
LINK = re.compile(r"\]\(([^)\s]+)\)")
HYDRA_APPS = {"semdp-train": "train", "semdp-plan": "plan", "semdp-toy": "toy"}


# --- paths -------------------------------------------------------------------------------------

def _path_words(text: str) -> Iterator[str]:
    """Words of ``text`` that look like repository paths (placeholders and gym ids left out)."""
    for match in PATH_WORD.finditer(text):
        word = match.group(1).split("::")[0].rstrip(".:")
        if PLACEHOLDER_CHARS & set(word) or GYM_ID.match(word):
            continue
        yield word


def missing_paths(markdown: str, base: Path) -> list[str]:
    """Repository paths named in ``markdown`` (a file in folder ``base``) that do not exist."""
    named: set[str] = set()
    for block in FENCE.findall(markdown):
        named |= set(_path_words(block))
    prose = FENCE.sub("", markdown)
    for span in CODE_SPAN.findall(prose):
        named |= set(_path_words(span))
    missing = []
    for word in sorted(named):
        if word.startswith("outputs/") and not word.startswith("outputs/reference"):
            continue  # written by the apps, not committed
        if not (ROOT / word).exists():
            missing.append(word)
    for target in LINK.findall(prose):
        target = target.split("#")[0]
        if not target or re.match(r"^[a-z]+:", target):
            continue
        if target.startswith("figures/"):
            if not (REFERENCE / target.removeprefix("figures/")).is_file():
                missing.append(target)
        elif not (base / target).exists():
            missing.append(target)
    return missing


@pytest.mark.parametrize("doc", DOC_FILES, ids=lambda p: str(p.relative_to(ROOT)))
def test_named_paths_exist(doc: Path) -> None:
    assert not missing_paths(doc.read_text(encoding="utf-8"), doc.parent)


# --- commands ----------------------------------------------------------------------------------

def shown_commands(markdown: str) -> list[list[str]]:
    """Every ``semdp-*`` command in the fenced blocks of ``markdown``, as argument lists."""
    commands = []
    for block in FENCE.findall(markdown):
        for line in block.replace("\\\n", " ").splitlines():
            line = re.sub(r"<[^<>]*>", "PLACEHOLDER", line)
            try:
                words = shlex.split(line, comments=True)
            except ValueError:  # a Python line with an unmatched quote
                continue
            command: list[str] = []
            for word in [*words, "&&"]:
                if word in ("&&", "||", ";", "|", "&"):
                    if command and command[0].startswith("semdp-"):
                        commands.append(command)
                    command = []
                else:
                    command.append(word)
    return commands


def _sweep_values(override: str) -> list[str]:
    """``key=a,b`` -> ``[key=a, key=b]`` (``range(0,3)`` -> its values); ``a|b|c`` (the guides'
    "one of") -> each; an override that sweeps nothing -> itself."""
    key, sep, value = override.partition("=")
    if sep and "|" in value and not value.startswith(("'", '"')):
        return [f"{key}={v}" for v in value.split("|")]
    parsed = OverridesParser.create().parse_overrides([override])[0]
    if not parsed.is_sweep_override():
        return [override]
    return [f"{parsed.get_key_element()}={v}" for v in parsed.sweep_string_iterator()]


def _variants(args: list[str]) -> list[list[str]]:
    """Override lists that together try every swept value once: the first value of every
    sweep, then each other value of one sweep with the first of the others."""
    values = [_sweep_values(o) for o in args]
    first = [v[0] for v in values]
    variants = [first]
    for i, options in enumerate(values):
        variants += [[*first[:i], other, *first[i + 1:]] for other in options[1:]]
    return variants


def _hydra_overrides(args: list[str]) -> list[str]:
    """The overrides of a Hydra app's command line, without ``-m``/``--cfg``/``--resolve``."""
    overrides, skip = [], False
    for arg in args:
        if skip:
            skip = False
        elif arg in ("-m", "--multirun", "--resolve"):
            pass
        elif arg in ("--cfg", "-c", "--package", "-p"):
            skip = True
        elif arg.endswith("=PLACEHOLDER") and (CONF_DIR / arg.split("=")[0]).is_dir():
            pass  # a group choice left open (`experiment=<preset>`): the default composes
        else:
            overrides.append(arg)
    return overrides


def _check_eval(args: list[str]) -> None:
    from semdp.evaluation import zoo
    from semdp.evaluation.options import SHORTHANDS

    if args[:1] in (["-h"], ["--help"]):
        return
    assert args, "semdp-eval needs a run directory or zoo:NAME"
    if args[0].startswith(zoo.PREFIX) and "PLACEHOLDER" not in args[0]:
        name = args[0].removeprefix(zoo.PREFIX)
        assert name in zoo.entries(), f"no zoo entry {name!r} in outputs/reference/zoo.yaml"
    top = set(compose_config("train"))
    for arg in args[1:]:
        if arg.startswith("[") or (arg.endswith("]") and "=" not in arg) or arg == "...":
            continue  # a usage line's optional part, `[key=value ...]`
        key = arg.partition("=")[0].lstrip("+")
        assert "=" in arg, f"semdp-eval takes key=value settings, got {arg!r}"
        assert key in SHORTHANDS or key.split(".")[0] in top, f"semdp-eval: unknown key {key!r}"


def _check_bench(args: list[str]) -> None:
    import importlib

    from semdp.benchmarks.arguments import parse_args
    from semdp.cli.bench import SUITES

    assert args, "semdp-bench needs a suite"
    if args[0] == "ab":  # `semdp-bench ab [key=value] -- <command>`: the command is checked too
        from semdp.benchmarks.ab import DEFAULTS, split_command

        items, timed = split_command(args[1:])
        parse_args("ab", items, DEFAULTS)
        if timed[0].startswith("semdp-"):
            check_command(timed)
        return
    for suite in args[0].split("|"):
        assert suite in SUITES, f"semdp-bench: unknown suite {suite!r}"
        defaults = getattr(importlib.import_module(SUITES[suite]), "DEFAULTS", None)
        if len(args[0].split("|")) == 1 and defaults is not None and suite != "safety":
            parse_args(suite, args[1:], defaults)


def _check_report(args: list[str]) -> None:
    known = {"--out", "--digits", "--order", "--compare", "--late", "--at", "-h", "--help"}
    flags = [arg.split("=")[0] for arg in args if arg.startswith("-")]
    assert all(flag in known for flag in flags), f"semdp-report: unknown option in {flags}"
    assert any(not arg.startswith("-") for arg in args) or "--help" in args, "no sweep dir"


def _compose(app: str, overrides: list[str]) -> None:
    """Compose (and resolve) the app's config as ``--cfg job`` would; type-check
    ``semdp-train``'s overrides as the app does."""
    cfg = compose_config(HYDRA_APPS[app], overrides)
    OmegaConf.to_container(cfg, resolve=True)
    if app == "semdp-train":
        from hydra import initialize_config_dir

        from semdp.cli.override_types import wrong_types

        with initialize_config_dir(config_dir=str(CONF_DIR), version_base="1.3"):
            reason = wrong_types(cfg, "train", overrides)
        assert reason is None, reason


def check_command(command: list[str]) -> None:
    """Raise (an exception naming the fault) unless the ``semdp-*`` command composes."""
    app, args = command[0], command[1:]
    if app in HYDRA_APPS:
        overrides = _hydra_overrides(args)
        if "hydra/launcher=cluster_ray" in overrides:
            assert any(o.startswith("hydra.sweep.dir=") for o in overrides), (
                "a Ray sweep needs an absolute hydra.sweep.dir "
                "(conf/hydra/launcher/cluster_ray.yaml)")
        for variant in _variants(overrides):
            _compose(app, variant)
    elif app == "semdp-eval":
        _check_eval(args)
    elif app == "semdp-bench":
        _check_bench(args)
    elif app == "semdp-report":
        _check_report(args)
    else:
        raise AssertionError(f"{app} is not an app of this project (pyproject.toml)")


def _all_commands() -> list[tuple[str, ...]]:
    seen: dict[tuple[str, ...], None] = {}
    for doc in DOC_FILES:
        for command in shown_commands(doc.read_text(encoding="utf-8")):
            seen.setdefault(tuple(command), None)
    return list(seen)


def test_shown_commands_compose() -> None:
    commands = _all_commands()
    assert len(commands) > 20  # the guides show commands; an empty scan would prove nothing
    failures = []
    for command in commands:
        try:
            check_command(list(command))
        except Exception as exc:
            failures.append(f"{shlex.join(command)}\n    {type(exc).__name__}: {exc}")
    assert not failures, "\n".join(failures)


# --- planted defects: each check can fail --------------------------------------------------------

def test_planted_stale_path_is_found() -> None:
    page = "IPOPT options live in `solvers/planner/ipopt.py` and [the conf](../conf/nope.yaml)."
    assert missing_paths(page, ROOT / "docs") == ["solvers/planner/ipopt.py", "../conf/nope.yaml"]
    assert missing_paths("`solvers/planner/backends/ipopt.py`", ROOT / "docs") == []


def test_planted_missing_figure_is_found() -> None:
    assert missing_paths("![x](figures/toy/no_such_figure.png)", ROOT / "docs") == [
        "figures/toy/no_such_figure.png"]
    assert missing_paths("![x](figures/toy/fig_2_1.png)", ROOT / "docs") == []


def test_placeholders_and_run_outputs_are_not_paths() -> None:
    page = ("`outputs/train/<time>_x`, `sims/SafetyPointPush1-v0`, `outputs/bench/sims.csv`, "
            "`semdp/algos/{ppo,gae}.py`")
    assert missing_paths(page, ROOT / "docs") == []


@pytest.mark.parametrize(
    ("block", "fault"),
    [
        ("semdp-train algo=ppo_lag no_such_key=1", "no_such_key"),
        ("semdp-train -m algo=ppo_lag,no_such_algo seed=0,1", "no_such_algo"),
        ("semdp-train -m algo=no_such_algo,ppo_lag seed=0,1", "no_such_algo"),
        ("semdp-train total_steps=many", "total_steps"),
        ("semdp-train -m experiment=semdp_push hydra/launcher=cluster_ray", "hydra.sweep.dir"),
        ("semdp-plan backend=ipopt no_such_key=2", "no_such_key"),
        ("semdp-eval zoo:no_such_policy", "no_such_policy"),
        ("semdp-eval <run dir> no_such_setting=3", "no_such_setting"),
        ("semdp-bench no_such_suite", "no_such_suite"),
        ("semdp-bench planner no_such_key=1", "no_such_key"),
        ("semdp-bench ab base=HEAD~1 -- semdp-train no_such_key=1", "no_such_key"),
        ("semdp-bench ab no_such_key=1 -- semdp-toy", "no_such_key"),
        ("semdp-report <sweep> --no-such-option", "--no-such-option"),
    ],
    ids=["unknown-key", "unknown-sweep-option-2nd", "unknown-sweep-option-1st", "wrong-type",
         "ray-without-sweep-dir", "plan-unknown-key", "unknown-zoo-entry",
         "unknown-eval-setting", "unknown-bench-suite", "unknown-bench-key",
         "ab-timed-command-broken", "ab-unknown-key",
         "unknown-report-option"],
)
def test_planted_broken_command_fails(block: str, fault: str) -> None:
    (command,) = shown_commands(f"```bash\n{block}\n```")
    with pytest.raises((Exception, SystemExit)) as raised:
        check_command(command)
    assert fault in str(raised.value), raised.value


def test_planted_good_commands_pass() -> None:
    block = ("```bash\nsemdp-train -m algo=ppo_lag,cpo seed=0,1 budget=ci|laptop  # a comment\n"
             "semdp-eval <run dir> episodes=3 && semdp-bench planner n=5\n```")
    commands = shown_commands(block)
    assert [c[0] for c in commands] == ["semdp-train", "semdp-eval", "semdp-bench"]
    for command in commands:
        check_command(command)
