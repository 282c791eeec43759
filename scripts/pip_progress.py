"""Shorten ``pip install -v``'s output on stdin to its steps, as they come, for ``scripts/setup.sh``.

Kept: the packages pip collects or finds installed (eight names a line), the build of stickslip with setup.py's
own ``stickslip:`` lines (one per compiled extension), what pip installs, and pip's errors. Standard library
only: it runs before the virtual environment has anything.
"""

import re
import sys

#: a line that names one dependency (group 1 or 2: its name): a requirement, or a wheel file
DEPENDENCY = re.compile(r"^(?:(?:Collecting|Requirement already satisfied:) ([A-Za-z0-9_.-]+)"
                        r"|Processing \S*/([A-Za-z0-9_.]+)-)")
#: pip's steps: pattern -> what to say
STEPS = {
    re.compile(r"Installing build dependencies: started"): "installing the build requirements (setuptools, mypy)",
    re.compile(r"Preparing (editable )?metadata .*: started"): "reading the metadata of stickslip",
    re.compile(r"Building (editable|wheel) for stickslip .*: started"): "building stickslip",
}
NAMES_PER_LINE = 8


def packages(n):
    return f"{n} package" if n == 1 else f"{n} packages"


def say(text):
    print(f"setup: {text}", flush=True)


def main(lines):
    names = []

    def flush():
        if names:
            say(f"pip: dependencies: {', '.join(names)}")
            names.clear()

    for line in lines:
        line = line.rstrip("\n")
        dependency = DEPENDENCY.match(line)
        if dependency:
            names.append(dependency.group(1) or dependency.group(2))
            if len(names) == NAMES_PER_LINE:
                flush()
        elif line.lstrip().startswith("stickslip: "):
            flush()
            say(line.lstrip())
        elif line.startswith("Installing collected packages: "):
            flush()
            say(f"pip: installing {packages(len(line.split(', ')))} into .venv")
        elif line.startswith("Successfully installed "):
            say(f"pip: installed {packages(len(line.split()) - 2)}")
        elif line.startswith(("ERROR", "error:")):
            flush()
            print(line, flush=True)
        else:
            step = next((text for pattern, text in STEPS.items() if pattern.search(line)), None)
            if step is not None:
                flush()
                say(f"pip: {step}")
    flush()


if __name__ == "__main__":
    main(sys.stdin)
