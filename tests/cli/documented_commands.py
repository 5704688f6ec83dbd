#!/usr/bin/python3
"""Every command the front door and the command references show still exists (issue 61).

Usage: documented_commands.py BIN_DIR DOC...

For each command line in the documents' code blocks (indented by four spaces or fenced) that runs
invr, invr-lab, invr-server or invr-worker: its subcommand path must exist (`--help` of it exits 0)
and every option written on it (`--name`, `-X`) must be one that help lists. Lines continued on the
next line (starting with `[` or `--`) belong to the command above; `&&` and a trailing `&` separate
commands; a `#` after two spaces starts a comment."""
import re
import subprocess
import sys
from pathlib import Path

PROGRAMS = ("invr", "invr-lab", "invr-server", "invr-worker")


def code_lines(text):
    fenced = False
    for line in text.splitlines():
        if line.strip().startswith("```"):
            fenced = not fenced
            continue
        if fenced or line.startswith("    "):
            yield line


def commands(text):
    """(command text, line) pairs, continuation lines joined."""
    out = []
    for line in code_lines(text):
        body = re.split(r"\s{2,}#|^\s*#", line)[0].rstrip()
        stripped = body.strip()
        if not stripped:
            continue
        if out and (stripped.startswith("[") or stripped.startswith("--")) and not re.match(r"\S*invr", stripped):
            out[-1] = (out[-1][0] + " " + stripped, out[-1][1])
            continue
        for part in re.split(r"\s&&\s|\s&$", stripped):
            part = part.strip().rstrip("&").strip()
            first = part.split()[0] if part.split() else ""
            if Path(first).name in PROGRAMS:
                out.append((part, line.strip()))
    return out


def help_text(bin_dir, prog, path):
    proc = subprocess.run([str(Path(bin_dir) / prog), *path, "--help"], capture_output=True, text=True, timeout=60)
    return proc.returncode, proc.stdout + proc.stderr


def subcommands(help_out):
    """Names help lists as subcommands (CLI11: an indented name at the start of a line, under a
    SUBCOMMANDS heading or a group heading of its own)."""
    names = set()
    in_options = False
    for line in help_out.splitlines():
        if re.match(r"^(options|positionals)\b", line.strip(), re.I):
            in_options = True
            continue
        if line and not line.startswith(" "):
            in_options = False  # a new heading (SUBCOMMANDS:, a group)
            continue
        m = re.match(r"^\s{2}([a-z][a-z0-9-]*)\s", line + " ")
        if m and not in_options:
            names.add(m.group(1))
    return names


def main():
    bin_dir = sys.argv[1]
    failures = []
    checked = 0
    cache = {}
    for doc in sys.argv[2:]:
        for cmd, line in commands(Path(doc).read_text()):
            tokens = cmd.split()
            prog = Path(tokens[0]).name
            path = []
            key = (prog, ())
            if key not in cache:
                cache[key] = help_text(bin_dir, prog, [])
            code, out = cache[key]
            rest = tokens[1:]
            while rest and re.fullmatch(r"[a-z][a-z0-9-]*", rest[0]) and rest[0] in subcommands(out):
                path.append(rest.pop(0))
                key = (prog, tuple(path))
                if key not in cache:
                    cache[key] = help_text(bin_dir, prog, path)
                code, out = cache[key]
            checked += 1
            where = f"{doc}: `{line}`"
            if code != 0:
                failures.append(f"{where}: `{prog} {' '.join(path)} --help` exited {code}")
                continue
            if prog in ("invr", "invr-lab") and not path and not (rest and rest[0].startswith("--")):
                failures.append(f"{where}: no {prog} command named (got {rest[:1]})")
                continue
            # A word where only subcommands go (the command takes no positional argument).
            if rest and re.fullmatch(r"[a-z][a-z0-9-]*", rest[0]) and subcommands(out) and not re.search(r"^positionals", out, re.I | re.M):
                failures.append(f"{where}: `{prog} {' '.join(path)}` has no command '{rest[0]}'")
                continue
            for opt in re.findall(r"(?<![\w-])(--[a-z][a-z0-9-]*|-[A-Za-z])(?![\w-])", " ".join(rest)):
                if not re.search(r"(^|[\s,\[])" + re.escape(opt) + r"(?![\w-])", out, re.M):
                    failures.append(f"{where}: `{prog} {' '.join(path)}` has no option {opt}")
    print(f"documented_commands: {checked} commands checked in {len(sys.argv) - 2} documents")
    if checked < 10:
        failures.append(f"only {checked} commands found: the parser no longer reads the documents")
    for f in failures:
        print("FAIL", f)
    sys.exit(1 if failures else 0)


if __name__ == "__main__":
    main()
