#!/usr/bin/python3
"""Fails on a product function over the length limit that the allowlist does not name, and on an
allowlist entry that is no longer over it (so the list only shrinks).

    check_function_length.py SOURCE_DIR [--allowlist FILE] [--max LINES] [--pmccabe PMCCABE]

Product code is every C and C++ source and header of SOURCE_DIR's tree (git's tracked and
untracked-not-ignored files; the whole folder when it is not a git tree) outside the folders that
are not product code (tests/, bench/, fuzz/, ...). Each function's length is pmccabe's (Debian's
package pmccabe): its lines from the line of its name to its closing brace. pmccabe reads C and old
C++; the text it is given has the newer C++ it does not know made neutral, line for line (nested
namespace names, digit separators, attributes, override/final, raw string contents), so the
reported lines are the source's. A file pmccabe still cannot read is a finding too: the check
would be blind there.

Allowlist lines: `path | qualified::name | reason` (one line of why it is long and where its split
is planned); `#` starts a comment. Exit 0: every long function is listed and every entry is long;
1: findings; 2: the allowlist cannot be read; 77: pmccabe is not installed (reported as skipped).
"""
import argparse
import os
import re
import shutil
import subprocess
import sys
import tempfile

NOT_PRODUCT = ("tests", "bench", "fuzz", "build", "web", "node_modules", "data", "docs", "packaging", "scripts")
SOURCE_EXT = (".cpp", ".hpp", ".h", ".c", ".cc")
NS_MARK = "__NS__"

NESTED_NAMESPACE = re.compile(r"^(\s*(?:inline\s+)?namespace\s+)([A-Za-z_]\w*(?:::[A-Za-z_]\w*)+)(\s*\{)", re.M)
DIGIT_SEPARATOR = re.compile(r"(?<=[0-9])'(?=[0-9])")
UNKNOWN_TO_PMCCABE = re.compile(r"\boverride\b|\bfinal\b|\[\[[^\]]*\]\]|__attribute__\s*\(\((?:[^()]|\([^()]*\))*\)\)")
RAW_STRING = re.compile(r'R"([^(\s"\\]{0,16})\((.*?)\)\1"', re.S)
PMCCABE_LINE = re.compile(r"^(\d+)\s+(\d+)\s+(\d+)\s+(\d+)\s+(\d+)\s+(.*)\((\d+)\):\s+(.*)$")


class Unreadable(Exception):
    pass


def product_files(root):
    """Product sources and headers, relative to `root`, sorted."""
    try:
        out = subprocess.run(["git", "-C", root, "ls-files", "--cached", "--others", "--exclude-standard"],
                             capture_output=True, text=True, check=True).stdout.splitlines()
    except (OSError, subprocess.CalledProcessError):
        out = []
        for folder, dirs, files in os.walk(root):
            dirs[:] = [d for d in dirs if not d.startswith(".")]
            out += [os.path.relpath(os.path.join(folder, f), root) for f in files]
    return sorted(f for f in out if f.endswith(SOURCE_EXT) and f.split("/")[0] not in NOT_PRODUCT
                  and os.path.isfile(os.path.join(root, f)))


def neutral_text(text):
    """`text` with what pmccabe misreads replaced by what it reads, keeping every line where it is."""
    text = RAW_STRING.sub(lambda m: 'R""' + re.sub(r"[^\n]", " ", m.group(0)[3:]), text)
    text = NESTED_NAMESPACE.sub(lambda m: m.group(1) + m.group(2).replace("::", NS_MARK) + m.group(3), text)
    text = DIGIT_SEPARATOR.sub("", text)
    return UNKNOWN_TO_PMCCABE.sub(lambda m: " " * len(m.group(0)), text)


def measure(pmccabe, root, files):
    """[(path, line, name, lines)] of every function; [finding] for each file pmccabe cannot read."""
    functions, findings = [], []
    with tempfile.TemporaryDirectory(prefix="lw-function-length-") as tmp:
        for rel in files:
            with open(os.path.join(root, rel), encoding="utf-8", errors="replace") as f:
                text = neutral_text(f.read())
            copy = os.path.join(tmp, rel)
            os.makedirs(os.path.dirname(copy), exist_ok=True)
            with open(copy, "w", encoding="utf-8") as f:
                f.write(text)
            # One file a run: pmccabe aborts (and reports nothing more) on some inputs.
            r = subprocess.run([pmccabe, rel], cwd=tmp, capture_output=True, text=True)
            if r.returncode != 0 or r.stderr.strip():
                said = (r.stderr.strip().splitlines() or [f"exit {r.returncode}"])[0]
                findings.append(f"{rel}: pmccabe cannot read it ({said}): its functions are not measured; make the "
                                "construct plain or teach neutral_text() in tests/style/check_function_length.py")
                continue
            for line in r.stdout.splitlines():
                m = PMCCABE_LINE.match(line)
                if m:
                    functions.append((rel, int(m.group(7)), m.group(8).replace(NS_MARK, "::"), int(m.group(5))))
    return functions, findings


def read_allowlist(path):
    """{(path, name): reason}."""
    entries = {}
    try:
        with open(path, encoding="utf-8") as f:
            lines = f.read().splitlines()
    except OSError as e:
        raise Unreadable(f"{path}: {e.strerror}")
    for n, line in enumerate(lines, 1):
        line = line.split("#", 1)[0].strip()
        if not line:
            continue
        parts = [p.strip() for p in line.split("|")]
        if len(parts) != 3 or not all(parts):
            raise Unreadable(f"{path}:{n}: expected `path | qualified::name | reason`, got '{line}'")
        if (parts[0], parts[1]) in entries:
            raise Unreadable(f"{path}:{n}: {parts[0]} {parts[1]} is listed twice")
        entries[(parts[0], parts[1])] = parts[2]
    return entries


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("source_dir")
    ap.add_argument("--allowlist", default=os.path.join(here, "function_length_allowlist.txt"))
    ap.add_argument("--max", type=int, default=120, help="the longest a function may be, in lines")
    ap.add_argument("--pmccabe", default="pmccabe")
    args = ap.parse_args()
    pmccabe = shutil.which(args.pmccabe)
    if not pmccabe:
        print(f"check_function_length: {args.pmccabe} not found (Debian's package pmccabe; scripts/install-deps)")
        return 77
    try:
        allowed = read_allowlist(args.allowlist)
    except Unreadable as e:
        print(f"check_function_length: {e}")
        return 2
    root = os.path.abspath(args.source_dir)
    functions, findings = measure(pmccabe, root, product_files(root))
    longest = {}
    for rel, line, name, lines in functions:
        if lines > args.max and lines > longest.get((rel, name), (0, 0))[1]:
            longest[(rel, name)] = (line, lines)
    for (rel, name), (line, lines) in sorted(longest.items()):
        if (rel, name) not in allowed:
            findings.append(f"{rel}:{line}: {name} is {lines} lines, over {args.max}, and not in the allowlist: "
                            "split it along its stages")
    for (rel, name) in sorted(allowed):
        if (rel, name) not in longest:
            findings.append(f"{rel}: {name} is in the allowlist but no longer over {args.max} lines (or gone): "
                            "remove its entry, so the list only shrinks")
    for f in findings:
        print(f)
    if findings:
        print(f"check_function_length: {len(findings)} findings")
        return 1
    print(f"check_function_length: {len(functions)} functions measured, none over {args.max} lines beyond the "
          f"{len(allowed)} allowlisted")
    return 0


if __name__ == "__main__":
    sys.exit(main())
