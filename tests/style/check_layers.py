#!/usr/bin/python3
"""Checks the tree against the layer table of docs/architecture.md (## Layers).

    check_layers.py SOURCE_DIR [--cmake CMAKE] [--reply DIR]

Configures SOURCE_DIR into a temporary folder with a CMake file-API query (nothing is built), then
fails, naming each finding, on: a project library or program in no row of the table; a row naming
a target no CMakeLists.txt defines; a row naming in "may link" a row that is not on a lower floor;
a target linking (directly or through others) a library its row may not reach; a source or header
including a header of a folder its row may not reach, or a header whose .cpp is in a library it may
not reach. --reply reads an existing file-API reply folder instead of configuring (for tests of
this script). Exit 0: the tree keeps the table; 1: findings; 2: the table or the tree cannot be
read.
"""
import argparse
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile

SKIP_DIRS = ("tests", "bench", "fuzz", "build", "web", "node_modules", "data", "docs", "packaging", "scripts")
SOURCE_EXT = (".cpp", ".hpp", ".h", ".c", ".cc")
INCLUDE = re.compile(r'^\s*#\s*include\s+"([^"]+)"', re.M)


class Unreadable(Exception):
    pass


def floor_value(text):
    """'2½' -> 2.5, '3' -> 3."""
    text = text.strip().replace("½", ".5")
    try:
        return float(text)
    except ValueError:
        raise Unreadable(f"floor '{text}' is not a number")


def read_table(doc_path):
    """Rows of the layer table: floor, folder, names, may_link."""
    try:
        with open(doc_path, encoding="utf-8") as f:
            text = f.read()
    except OSError as e:
        raise Unreadable(f"{doc_path}: {e.strerror}")
    m = re.search(r"^## Layers\n(.*?)(?=^## )", text, re.M | re.S)
    if not m:
        raise Unreadable(f"{doc_path}: no '## Layers' section")
    rows = []
    for line in m.group(1).splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) < 4 or not line.lstrip().startswith("|") or cells[0] in ("floor", "") or set(cells[0]) <= set("-"):
            continue
        folder = re.findall(r"`([^`]+)/`", cells[1])
        names = re.findall(r"`([^`]+)`", cells[2])
        may = re.findall(r"`([^`]+)`", cells[3])
        if len(folder) != 1 or not names:
            raise Unreadable(f"{doc_path}: layer table row '{line.strip()}' needs one `folder/` and at least one `target`")
        rows.append({"floor": floor_value(cells[0]), "folder": folder[0], "names": names, "may": may})
    if not rows:
        raise Unreadable(f"{doc_path}: the '## Layers' section has no table rows")
    return rows


def defined_names(source_dir):
    """Target names CMakeLists.txt files define: add_library, add_executable, or the first argument
    of a project function that makes an image (lw_stm32_image), cross-only targets included."""
    names = set()
    for root, dirs, files in os.walk(source_dir):
        dirs[:] = [d for d in dirs if not d.startswith(".") and d not in ("build", "node_modules")]
        for f in files:
            if f == "CMakeLists.txt" or f.endswith(".cmake"):
                with open(os.path.join(root, f), encoding="utf-8", errors="replace") as fh:
                    names.update(re.findall(r"\b(?:add_library|add_executable|lw_\w*image)\(\s*([A-Za-z0-9_.+-]+)[\s)]", fh.read()))
    return names


def configure(source_dir, cmake, work):
    query = os.path.join(work, ".cmake", "api", "v1", "query")
    os.makedirs(query)
    open(os.path.join(query, "codemodel-v2"), "w").close()
    generator = ["-G", "Ninja"] if shutil.which("ninja") else []
    run = subprocess.run([cmake, "-S", source_dir, "-B", work, *generator], capture_output=True, text=True)
    if run.returncode != 0:
        raise Unreadable(f"cmake could not configure {source_dir}:\n{run.stdout[-2000:]}{run.stderr[-2000:]}")
    return os.path.join(work, ".cmake", "api", "v1", "reply")


def read_targets(reply):
    """name -> {folder, type, deps (transitive, project targets), sources (paths from the top)}."""
    try:
        index = [f for f in os.listdir(reply) if f.startswith("codemodel-v2-")]
        with open(os.path.join(reply, index[0]), encoding="utf-8") as f:
            model = json.load(f)
    except (OSError, IndexError, ValueError) as e:
        raise Unreadable(f"no readable CMake file-API codemodel in {reply}: {e}")
    by_id = {}
    for t in model["configurations"][0]["targets"]:
        with open(os.path.join(reply, t["jsonFile"]), encoding="utf-8") as f:
            by_id[t["id"]] = json.load(f)
    targets = {}
    for d in by_id.values():
        top = d["paths"]["source"].split("/")[0]
        if d["type"] == "UTILITY" or top in SKIP_DIRS or top == ".":
            continue
        targets[d["name"]] = {
            "folder": top,
            "deps": sorted(by_id[x["id"]]["name"] for x in d.get("dependencies", []) if x["id"] in by_id),
            "sources": [s["path"] for s in d.get("sources", [])],
        }
    return targets


class Layers:
    def __init__(self, rows):
        self.rows = rows
        self.row_of = {}
        for r in rows:
            for n in r["names"]:
                self.row_of[n] = r
        self.reach = {}

    def reachable(self, row):
        """The names a row's targets may link: its own row, its may-link rows' targets, transitively."""
        key = id(row)
        if key not in self.reach:
            self.reach[key] = set(row["names"])
            for m in row["may"]:
                if m in self.row_of:
                    self.reach[key].add(m)
                    self.reach[key] |= self.reachable(self.row_of[m]) if self.row_of[m] is not row else set()
        return self.reach[key]

    def folders_of(self, names):
        return {self.row_of[n]["folder"] for n in names if n in self.row_of}


def check(source_dir, rows, targets, defined):
    findings = []
    layers = Layers(rows)
    for r in rows:
        for n in r["names"] + r["may"]:
            if n not in defined and n not in targets:
                findings.append(f"the layer table names `{n}` (row {r['folder']}/), which no CMakeLists.txt defines")
        for m in r["may"]:
            if m in layers.row_of and layers.row_of[m]["floor"] >= r["floor"]:
                findings.append(f"row {r['folder']}/ (floor {r['floor']:g}) may link `{m}`, which is not on a lower floor "
                                f"({layers.row_of[m]['folder']}/, floor {layers.row_of[m]['floor']:g})")
    for name, t in sorted(targets.items()):
        row = layers.row_of.get(name)
        if row is None:
            findings.append(f"`{name}` ({t['folder']}/) is in no row of the layer table in docs/architecture.md")
            continue
        if row["folder"] != t["folder"]:
            findings.append(f"`{name}` is defined in {t['folder']}/ but its row is {row['folder']}/")
        allowed = layers.reachable(row)
        for dep in t["deps"]:
            if dep in layers.row_of and dep not in allowed:
                findings.append(f"`{name}` links `{dep}` ({t['folder']}/ -> {layers.row_of[dep]['folder']}/), which the "
                                f"layer table does not allow (its row may link: {', '.join(row['may']) or 'nothing'})")
    findings += check_includes(source_dir, layers, targets)
    return findings


def check_includes(source_dir, layers, targets):
    """Every quoted include of a project folder's header, against the including file's row(s)."""
    findings = []
    include_folders = {f for f in os.listdir(source_dir) if os.path.isdir(os.path.join(source_dir, f, "include", f))}
    owner_of_file = {}  # a source's path -> the targets that compile it
    library_of_stem = {}  # folder/stem -> the library whose .cpp has that stem
    for name, t in targets.items():
        for s in t["sources"]:
            owner_of_file.setdefault(s, set()).add(name)
            if s.endswith(".cpp") and not name.startswith("linerwatch"):
                library_of_stem[(t["folder"], os.path.splitext(os.path.basename(s))[0])] = name
    for folder in sorted({r["folder"] for r in layers.rows}):
        for root, dirs, files in os.walk(os.path.join(source_dir, folder)):
            dirs[:] = [d for d in dirs if not d.startswith(".")]
            for f in files:
                if not f.endswith(SOURCE_EXT):
                    continue
                path = os.path.relpath(os.path.join(root, f), source_dir)
                owners = owner_of_file.get(path) or {n for r in layers.rows if r["folder"] == folder for n in r["names"]}
                allowed = set().union(*(layers.reachable(layers.row_of[n]) for n in owners if n in layers.row_of))
                allowed_folders = layers.folders_of(allowed) | {folder}
                with open(os.path.join(root, f), encoding="utf-8", errors="replace") as fh:
                    text = fh.read()
                for inc in INCLUDE.findall(text):
                    top = inc.split("/")[0]
                    if "/" not in inc or top not in include_folders:
                        continue
                    if top not in allowed_folders:
                        findings.append(f"{path} includes \"{inc}\" ({folder}/ -> {top}/), which the layer table does not allow")
                        continue
                    lib = library_of_stem.get((top, os.path.splitext(os.path.basename(inc))[0]))
                    if lib and lib not in allowed:
                        findings.append(f"{path} includes \"{inc}\", whose code is in `{lib}`, which its row may not link")
    return findings


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("source_dir")
    ap.add_argument("--cmake", default="cmake")
    ap.add_argument("--reply", help="an existing CMake file-API reply folder (skips configuring)")
    ap.add_argument("--doc", help="the document holding the table (default SOURCE_DIR/docs/architecture.md)")
    a = ap.parse_args()
    source_dir = os.path.abspath(a.source_dir)
    try:
        rows = read_table(a.doc or os.path.join(source_dir, "docs", "architecture.md"))
        if a.reply:
            targets = read_targets(a.reply)
        else:
            with tempfile.TemporaryDirectory(prefix="lw-layers-") as work:
                targets = read_targets(configure(source_dir, a.cmake, work))
        findings = check(source_dir, rows, targets, defined_names(source_dir))
    except Unreadable as e:
        print(f"check_layers: {e}", file=sys.stderr)
        return 2
    for f in findings:
        print(f"check_layers: {f}")
    if findings:
        print(f"check_layers: {len(findings)} finding(s); fix the code or change the table in docs/architecture.md")
        return 1
    print(f"check_layers: {len(targets)} targets and their includes keep the layer table ({len(rows)} rows)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
