#!/usr/bin/env python3
"""The suite's own rule (issue 57): no ctest test is judged by its output alone. PASS_REGULAR_EXPRESSION
makes ctest ignore a test's exit status, so a command that prints the expected words and then fails
would pass; tests that check a message use invr_test(... OUTPUT ...) (tests/expect.py) instead.

usage: suite_check.py TESTS_DIR   (exit 0: clean; 1: each offending line printed as file:line)
"""
import os
import re
import sys


def main():
    root = sys.argv[1] if len(sys.argv) > 1 else os.path.dirname(os.path.abspath(__file__))
    files, problems = 0, []
    for dirpath, _, names in os.walk(root):
        for name in sorted(names):
            if name != "CMakeLists.txt" and not name.endswith(".cmake"):
                continue
            path = os.path.join(dirpath, name)
            files += 1
            for n, line in enumerate(open(path, encoding="utf-8"), 1):
                code = re.sub(r"#.*", "", line)  # comments may name the property
                if "PASS_REGULAR_EXPRESSION" in code:
                    problems.append(f"{os.path.relpath(path, root)}:{n}: PASS_REGULAR_EXPRESSION ignores the exit status; use invr_test(... OUTPUT ...)")
    for p in problems:
        print(p)
    print(f"suite: {files} CMake files, {len(problems)} tests judged by output alone")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
