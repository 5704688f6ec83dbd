#!/usr/bin/env python3
"""Runs one test command and judges it by its exit status and its output together.

ctest's PASS_REGULAR_EXPRESSION ignores the exit status (a command that prints the expected words
and then exits 1 passes), so no test uses it: tests that check a message run through this wrapper
instead (tests/CMakeLists.txt, invr_test()).

usage: expect.py [--exit N] [--skip-exit N] [--output REGEX]... [--no-output REGEX]... -- COMMAND [ARG]...

  --exit N          the status the command must end with (default 0)
  --skip-exit N     a status that means "skipped" (the check could not run here): passed through
                    unchanged, so that ctest's SKIP_RETURN_CODE reports the test as skipped
  --output REGEX    must match somewhere in stdout + stderr (Python re, '.' matches newlines)
  --no-output REGEX must not match anywhere

The command's output is copied to stdout as it arrives. Exit 0 when every check holds, 1 when one
fails (each failed check is named on the last lines), the skip status when the command skipped.
"""
import re
import subprocess
import sys


def main(argv):
    if "--" not in argv:
        sys.exit("expect.py: no command (usage: expect.py [--exit N] [--output REGEX]... -- COMMAND ...)")
    split = argv.index("--")
    options, command = argv[:split], argv[split + 1:]
    if not command:
        sys.exit("expect.py: empty command after --")
    want_exit, skip_exit, must, must_not = 0, None, [], []
    i = 0
    while i < len(options):
        flag = options[i]
        if i + 1 >= len(options):
            sys.exit(f"expect.py: {flag} needs a value")
        value = options[i + 1]
        if flag == "--exit":
            want_exit = int(value)
        elif flag == "--skip-exit":
            skip_exit = int(value)
        elif flag == "--output":
            must.append(value)
        elif flag == "--no-output":
            must_not.append(value)
        else:
            sys.exit(f"expect.py: unknown option {flag}")
        i += 2
    proc = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
    chunks = []
    for line in iter(proc.stdout.readline, b""):
        chunks.append(line)
        sys.stdout.buffer.write(line)
        sys.stdout.buffer.flush()
    code = proc.wait()
    output = b"".join(chunks).decode("utf-8", "replace")
    if skip_exit is not None and code == skip_exit:
        print(f"expect.py: skipped (exit {code})")
        return code
    failures = []
    if code != want_exit:
        failures.append(f"exit status {code}, expected {want_exit}")
    for pattern in must:
        if not re.search(pattern, output, re.S):
            failures.append(f"output does not match: {pattern}")
    for pattern in must_not:
        if re.search(pattern, output, re.S):
            failures.append(f"output matches what it must not: {pattern}")
    for f in failures:
        print(f"expect.py: FAILED: {f}")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
