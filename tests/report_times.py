#!/usr/bin/env python3
"""Prints the ten slowest tests of a ctest run and its totals, from ctest's JUnit report
(`ctest --output-junit FILE`); deploy/test.sh calls it after every run.

usage: report_times.py JUNIT_XML [WALL_SECONDS]
"""
import sys
import xml.etree.ElementTree as ET


def main():
    path = sys.argv[1]
    wall = float(sys.argv[2]) if len(sys.argv) > 2 else None
    try:
        root = ET.parse(path).getroot()
    except (OSError, ET.ParseError) as e:
        print(f"report_times: no report ({e})")
        return 1
    cases = []
    for case in root.iter("testcase"):
        status = case.get("status", "run")
        if case.find("skipped") is not None or status in ("notrun", "disabled"):
            continue
        cases.append((float(case.get("time", 0)), case.get("name"), "FAILED" if case.find("failure") is not None else ""))
    cases.sort(reverse=True)
    total = sum(t for t, _, _ in cases)
    print(f"ten slowest of {len(cases)} tests:")
    for t, name, failed in cases[:10]:
        print(f"  {t:8.1f} s  {name} {failed}".rstrip())
    line = f"tests: {total:.0f} test-seconds in all"
    if wall is not None:
        line += f", {wall:.0f} s of wall time"
    print(line)
    return 0


if __name__ == "__main__":
    sys.exit(main())
