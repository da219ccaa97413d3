"""An independent reader of OMPL's benchmark log format, written from the grammar in OMPL's
doc/markdown/benchmark.md ("The benchmark logfile format", EBNF), not from our writer: it
checks each literal the grammar names and raises ValueError at the first line that breaks it.

    logfile      ::= preamble planners_data;
    preamble     ::= [version] experiment [exp_property_count exp_properties] hostname date
                     setup [cpuinfo] random_seed time_limit memory_limit [num_runs] total_time
                     [num_enums enums] num_planners;
    planner_data ::= planner_name EOL int " common properties" EOL planner_properties
                     int " properties for each run" EOL run_properties int " runs" EOL
                     run_measurements [progress ...] "." EOL;
    property_type ::= "BOOLEAN" | "INTEGER" | "REAL";
    run_measurement ::= data "; " | data "; " run_measurement;
    data ::= num | "inf" | "nan" | "";
"""

from __future__ import annotations

import re

NUM = r"[-+]?(\d+(\.\d*)?|\.\d+)([eE][-+]?\d+)?"


class _Lines:
    def __init__(self, text: str):
        if not text.endswith("\n"):
            raise ValueError("a log ends with EOL")
        self.lines = text[:-1].split("\n")
        self.i = 0

    def peek(self) -> str:
        return self.lines[self.i] if self.i < len(self.lines) else ""

    def take(self, pattern: str, what: str) -> re.Match:
        line = self.peek()
        match = re.fullmatch(pattern, line)
        if match is None:
            raise ValueError(f"line {self.i + 1}: expected {what}, got {line!r}")
        self.i += 1
        return match

    def optional(self, pattern: str) -> re.Match | None:
        match = re.fullmatch(pattern, self.peek())
        if match is not None:
            self.i += 1
        return match

    def block(self, what: str) -> str:
        self.take(r"<<<\|", f"{what} '<<<|'")
        body = []
        while self.peek() != "|>>>":
            if self.i >= len(self.lines):
                raise ValueError(f"{what} never ends with '|>>>'")
            body.append(self.peek())
            self.i += 1
        self.i += 1
        return "\n".join(body)


def _data(text: str, kind: str, where: str):
    if text in ("", "nan", "inf"):
        return None if text == "" else float(text)
    if not re.fullmatch(NUM, text):
        raise ValueError(f"{where}: {text!r} is not a number")
    if kind == "BOOLEAN":
        if text not in ("0", "1"):
            raise ValueError(f"{where}: BOOLEAN {text!r} is not 0 or 1")
        return text == "1"
    if kind == "INTEGER":
        if not re.fullmatch(r"[-+]?\d+", text):
            raise ValueError(f"{where}: INTEGER {text!r}")
        return int(text)
    return float(text)


def parse_ompl_log(text: str) -> dict:
    """The log as {version, experiment, properties, host, date, setup, cpuinfo, seed,
    time_limit, memory_limit, runs_per_planner, total_time, planners: [{name, common,
    properties: [(name, type)], runs: [{property: value}]}]}."""
    lines = _Lines(text)
    log: dict = {}
    version = lines.optional(r"(\S+) version (\S+)")
    log["version"] = version.groups() if version else None
    log["experiment"] = lines.take(r"Experiment (\S+)", "'Experiment NAME'").group(1)
    log["properties"] = {}
    count = lines.optional(r"(\d+) experiment properties")
    for _ in range(int(count.group(1)) if count else 0):
        m = lines.take(rf"(\S+) (BOOLEAN|INTEGER|REAL)=({NUM})", "'name TYPE=num'")
        log["properties"][m.group(1)] = (m.group(2), float(m.group(3)))
    log["host"] = lines.take(r"Running on (\S+)", "'Running on HOST'").group(1)
    log["date"] = lines.take(r"Starting at (.+)", "'Starting at DATE'").group(1)
    log["setup"] = lines.block("setup")
    log["cpuinfo"] = lines.block("cpuinfo") if lines.peek() == "<<<|" else None
    log["seed"] = int(lines.take(r"(\d+) is the random seed", "the random seed").group(1))
    log["time_limit"] = float(lines.take(rf"({NUM}) seconds per run", "time limit").group(1))
    log["memory_limit"] = float(lines.take(rf"({NUM}) MB per run", "memory limit").group(1))
    runs = lines.optional(r"(\d+) runs per planner")
    log["runs_per_planner"] = int(runs.group(1)) if runs else None
    log["total_time"] = float(lines.take(rf"({NUM}) seconds spent to collect the data",
                                         "total time").group(1))
    enums = lines.optional(r"(\d+) enum types?")
    for _ in range(int(enums.group(1)) if enums else 0):
        lines.take(r"[^|]+(\|[^|]+)+", "an enum")
    planners = int(lines.take(r"(\d+) planners", "'N planners'").group(1))
    log["planners"] = []
    for _ in range(planners):
        planner: dict = {"name": lines.take(r"(.+)", "a planner name").group(1)}
        common = int(lines.take(r"(\d+) common properties", "common properties").group(1))
        planner["common"] = dict(lines.take(r"(.+) = (.*)", "'name = value'").groups()
                                 for _ in range(common))
        count = int(lines.take(r"(\d+) properties for each run", "run properties").group(1))
        properties = [lines.take(r"(.+) (BOOLEAN|INTEGER|REAL)", "'name TYPE'").groups()
                      for _ in range(count)]
        planner["properties"] = properties
        planner["runs"] = []
        for _ in range(int(lines.take(r"(\d+) runs", "'N runs'").group(1))):
            where = f"line {lines.i + 1}"
            line = lines.take(r"([^;]*; )+", "a run: values each followed by '; '").group(0)
            values = line.split("; ")[:-1]
            if len(values) != count:
                raise ValueError(f"{where}: {len(values)} values for {count} properties")
            planner["runs"].append({name: _data(v, kind, where)
                                    for (name, kind), v in zip(properties, values, strict=True)})
        lines.take(r"\.", "'.' ending the planner's data")
        log["planners"].append(planner)
    if lines.i != len(lines.lines):
        raise ValueError(f"line {lines.i + 1}: text after the last planner")
    return log
