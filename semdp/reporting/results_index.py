"""The results page's index of every folder of ``outputs/reference/`` (current ones, then
those under ``archive/``): what it holds, the claims resting on it, its status, its runs, its
zoo policies and the command that rebuilds it, taken from its ``COMMAND.md`` (or
``README.md``).
"""

from __future__ import annotations

import re
from collections import defaultdict

from semdp.reporting.names import algorithm_name
from semdp.reporting.results_claims import listed_claims
from semdp.reporting.results_sources import Sources, kept_runs, zoo_entries


def _command_md_facts(text: str, record: str = "COMMAND.md") -> tuple[str, str | None, str]:
    """(title, runs line, rebuild command) of a folder's record (its COMMAND.md, else its
    README.md, named by ``record``)."""
    title = next((line[2:].strip() for line in text.splitlines() if line.startswith("# ")), "")
    title = re.sub(r"^Reference:\s*", "", title)
    runs = re.search(r"^- Runs: (\d+) \((\d+) completed\)", text, re.M)
    runs_text = f"{runs.group(1)}" if runs else None
    rebuild = re.search(r"rebuild or extend this folder with `([^`]+)`", text)
    if rebuild:
        return title, runs_text, rebuild.group(1).replace(" [more sweeps]", "")
    block = re.search(r"^```(?:bash)?\n(.*?)^```", text, re.M | re.S)
    commands = [line.split("  #")[0].strip() for line in (block.group(1) if block else "")
                .splitlines() if line.strip() and not line.lstrip().startswith("#")]
    if not commands:  # a command named in the prose
        commands = re.findall(r"`((?:semdp-|python -m )[^`]+)`", text)[:1]
    if not commands:
        return title, runs_text, f"see {record}"
    more = f" (and {len(commands) - 1} more in {record})" if len(commands) > 1 else ""
    return title, runs_text, commands[0] + more


def _banner(text: str) -> str:
    """The archive banner: the first paragraph, when it is a quote."""
    first = text.split("\n\n")[0]
    return " ".join(line.lstrip("> ") for line in first.splitlines()) if first.startswith(">") \
        else ""


def _replaced_by(banner: str) -> str:
    """The folders an archive banner names after 'replaced by'."""
    found = re.search(r"replaced by(.*?)(?:\.\s|\.$|$)", banner, re.I | re.S)
    names = re.findall(r"`(?:\.\./)*((?:archive/)?[a-z0-9_]+(?:/[a-z_]+\.md)?)`",
                       found.group(1) if found else "")
    return ", ".join(f"`{n}`" for n in dict.fromkeys(names))


def _clause(text: str) -> str:
    """A paragraph's first clause (up to its first colon or semicolon), links as their text."""
    text = re.sub(r"\[([^\]]*)\]\([^)]*\)", r"\1", text)
    return re.split(r"[:;]\s", text, maxsplit=1)[0].strip()


def _first_prose(text: str) -> str:
    """The first paragraph of a COMMAND.md that is prose (not a heading, list, table, quote
    or code)."""
    body = re.sub(r"^```.*?^```", "", text, flags=re.M | re.S)
    for paragraph in body.split("\n\n"):
        paragraph = paragraph.strip()
        if paragraph and not paragraph.startswith(("#", "-", "|", ">", "`", "Produced")):
            return " ".join(paragraph.split())
    return ""


def _runs_summary(sources: Sources, folder: str) -> str:
    """``methods × envs`` of the folder's kept runs ('' without runs)."""
    methods, envs = set(), set()
    for _, metrics in kept_runs(sources, folder):
        methods.add(algorithm_name(str(metrics.get("label") or metrics.get("algo"))))
        envs.add(str(metrics["env"]))
    if not methods:
        return ""
    ordered = sorted(methods, key=lambda name: (name != "Ours", name))
    return f"{', '.join(ordered)} × {', '.join(sorted(envs))}"


def folder_index(sources: Sources) -> str:
    """Every folder of outputs/reference: what, claims, status, runs, zoo policies, rebuild."""
    zoo = zoo_entries(sources)
    resting: dict[str, list[int]] = defaultdict(list)
    for number, claim in enumerate(listed_claims(sources), start=1):
        for folder in claim["folders"]:
            resting[folder].append(number)
    lines = ["## Every folder of `outputs/reference/`", "",
             "Current folders first, then the archived ones (`outputs/reference/archive/`: each "
             "`COMMAND.md`, or `README.md` where the folder has no commands of its own, opens "
             "with what the folder was, why it is archived and what replaces it). *Claims*: the "
             "claims above that rest on it; *runs*: the runs its report counts; *zoo*: its "
             "policies in `zoo.yaml` (`semdp-eval zoo:<entry>`); *rebuild*: the command, from "
             "that file.", "",
             "| folder | what | claims | status | runs | zoo | rebuild |",
             "|---|---|---|---|---|---|---|"]
    root = sources.root
    folders = sorted(p.name for p in root.iterdir() if p.is_dir() and p.name != "archive")
    folders += sorted(f"archive/{p.name}" for p in (root / "archive").iterdir() if p.is_dir())
    for folder in folders:
        record = next((name for name in ("COMMAND.md", "README.md")
                       if sources.exists(f"{folder}/{name}")), "COMMAND.md")
        text = sources.text(f"{folder}/{record}") if sources.exists(f"{folder}/{record}") else ""
        title, runs, rebuild = _command_md_facts(text, record)
        banner = _banner(text)
        if not title or title.strip("`") == folder.split("/")[-1]:
            title = (_clause(banner.removeprefix("**Archived.** "))
                     or _runs_summary(sources, folder) or _clause(_first_prose(text)))
        status = "current"
        if folder.startswith("archive/"):
            replaced = _replaced_by(banner)
            status = "archived" + (f"; replaced by {replaced}" if replaced else "")
        held = sorted(name for name, path in zoo.items() if path.startswith(folder + "/"))
        policies = ("–" if not held else f"{len(held)}: `{held[0]}`"
                    + (f" … `{held[-1]}`" if len(held) > 1 else ""))
        numbers = ", ".join(f"[{n}](#claim-{n})" for n in resting.get(folder, [])) or "–"
        rebuild = rebuild.replace("|", "\\|")
        lines.append(f"| `{folder}/` | {title} | {numbers} | {status} | {runs or '–'} | "
                     f"{policies} | `{rebuild}` |")
    return "\n".join(lines) + "\n"
