#!/usr/bin/env python3
"""The encode options' path through the encoder (issue 45): which functions read them, and how
often the path enters a file it has already left.

From a root function (default: assemble_parts, the staged encode's assemble), it follows every
call to a *carrier*: a function that takes a carrier type (EncodeOptions, SequenceEncoder, a struct
EncodeOptions holds, or a stage's settings struct derived from them: CARRIER_TYPES) or is a member
of SequenceEncoder. Calls are resolved by clang (the AST's referenced declaration), so a function of
the same name in another class or namespace (a namesake) is never taken for the one called; a
file-local function is its file's own.

It prints the functions in the order a depth-first walk first reaches them, with their files; the
files (a header and the source of its name counted as one), each with how often the path enters
it; and the returns. The path enters a file at every call from a function on it to one in another
file (each pair of caller and callee once; the root enters its own file once); a return is an
entry into a file the path had entered before: a stage calling back into the driver's file, or the
driver going back to a stage's. A call within one file enters nothing.

Usage: tools/options_trace.py [--root NAME] [--root-file FILE] [--carriers options|fields|settings] [--list]
  run from the repository root; clang++ parses each file it needs (-fsyntax-only), ~5 s a file,
  cached in $TMPDIR/options_trace-cache (default /tmp) by the flags and the contents of the file and of
  every header it includes (clang++ -M's list): a header's change re-parses only the units that
  include it.
"""
import argparse
import hashlib
import json
import os
import re
import subprocess
import sys
from pathlib import Path

# What carries the options, three ways (--carriers): the options and the driver's state alone
# ("options"); with the structs EncodeOptions holds, which the driver hands on whole ("fields"); and
# with each stage's settings that the driver derives from them ("settings", the default: a stage's
# internals that read its settings count too).
CARRIER_SETS = {
    "options": ["EncodeOptions", "SequenceEncoder"],
    "fields": ["EncodeOptions", "SequenceEncoder", "RegistrationOptions", "ConformalOptions", "DensityEqualisingOptions",
               "FieldPrecisionOptions", "TextureQualityOptions", "TrackingOptions"],
}
CARRIER_SETS["settings"] = CARRIER_SETS["fields"] + ["PlanSettings", "TextureSettings", "BuildSettings", "StageSettings"]
CARRIER_TYPES = CARRIER_SETS["settings"]
CARRIER_CLASSES = ["SequenceEncoder"]  # every member a carrier
SOURCE_DIRS = ["codec", "format", "tools"]
FUNCTION_KINDS = {"FunctionDecl", "CXXMethodDecl", "CXXConstructorDecl", "CXXDestructorDecl", "CXXConversionDecl"}
CACHE = Path(os.environ.get("TMPDIR", "/tmp")) / "options_trace-cache"


def compile_flags(build):
    flags = ["-std=c++20", "-fsyntax-only", "-DFACEMORPH_STATIC", '-DFACEMORPH_VERSION="0"', "-DFACEMORPH_HAVE_CHOLMOD",
             "-I.", "-Icodec/decoder/include", "-isystem", "/usr/include/eigen3", "-isystem", "/usr/include/suitesparse",
             "-isystem", "/usr/include/opencv4", "-Wno-everything"]
    if build and (Path(build) / "codec").is_dir():
        flags += ["-I" + str(Path(build))]
    return flags


FILE_DIGESTS = {}  # path -> sha256 of its bytes, each file read once a run


def file_digest(path):
    if path not in FILE_DIGESTS:
        FILE_DIGESTS[path] = hashlib.sha256(Path(path).read_bytes()).hexdigest()
    return FILE_DIGESTS[path]


def unit_key(path, flags):
    """What a unit's AST depends on: the flags, this script, the source and every header it includes
    (the project's, a build folder's generated ones and the system's: clang++ -M lists them), each by
    its contents. None where the headers cannot be listed (the unit is then parsed, not cached)."""
    deps_flags = [f for f in flags if f != "-fsyntax-only"] + ["-M", "-MT", "unit"]
    run = subprocess.run(["clang++"] + deps_flags + [str(path)], capture_output=True, text=True, check=False)
    if run.returncode != 0:
        return None
    files = sorted(set(run.stdout.replace("\\\n", " ").split()[1:]))  # past "unit:"
    h = hashlib.sha256()
    for part in [" ".join(flags), str(path), file_digest(__file__)] + ["%s %s" % (f, file_digest(f)) for f in files]:
        h.update(part.encode() + b"\0")
    return h.hexdigest()


def qual_type_params(qual_type):
    # "void (const EncodeOptions &, int) const" -> "const EncodeOptions &, int"
    t = re.sub(r"\s*(const|volatile|noexcept|&|&&)\s*$", "", (qual_type or "").strip())
    t = re.sub(r"\s*(const|volatile|noexcept|&|&&)\s*$", "", t)
    if not t.endswith(")"):
        return ""
    depth = 0
    for i in range(len(t) - 1, -1, -1):
        depth += {")": 1, "(": -1}.get(t[i], 0)
        if depth == 0:
            return t[i + 1:-1]
    return ""


UNPARSED = []  # the sources clang++ could not parse: the trace is then incomplete


def parse_unit(path, flags):
    CACHE.mkdir(parents=True, exist_ok=True)
    key = unit_key(path, flags)
    cached = CACHE / ((key or "none") + ".json")
    if key and cached.exists():
        return json.loads(cached.read_text())
    cmd = ["clang++"] + flags + ["-Xclang", "-ast-dump=json", "-Xclang", "-ast-dump-filter=facemorph::", str(path)]
    run = subprocess.run(cmd, capture_output=True, text=True, check=False)
    defs = summarise(run.stdout)
    if run.returncode != 0 or not defs:
        # Counted without this file's functions would be a path cut short: said, not cached.
        sys.stderr.write("options_trace: clang++ could not parse %s (%d): %s\n" % (path, run.returncode, run.stderr[-2000:]))
        UNPARSED.append(str(path))
        return defs
    if key:
        cached.write_text(json.dumps(defs))
    return defs


def summarise(text):
    """Every function defined in the dump: its key, file and the keys of what it calls."""
    decoder = json.JSONDecoder()
    roots, i = [], 0
    while True:
        while i < len(text) and text[i].isspace():
            i += 1
        if i >= len(text):
            break
        node, i = decoder.raw_decode(text, i)
        roots.append(node)

    state = {"file": ""}
    names = {}      # decl id -> key (functions) or qualified name (records)
    canonical = {}  # decl id -> id of its first declaration
    defs = {}

    def see_loc(loc):
        if not isinstance(loc, dict):
            return
        for sub in ("spellingLoc", "expansionLoc"):
            if sub in loc:
                see_loc(loc[sub])
        if "file" in loc:
            state["file"] = loc["file"]

    def see_node_locs(node):
        see_loc(node.get("loc"))
        rng = node.get("range")
        if isinstance(rng, dict):
            see_loc(rng.get("begin"))
            see_loc(rng.get("end"))

    def visit(node, scope, in_function):
        see_node_locs(node)
        kind = node.get("kind")
        file_here = state["file"]
        if kind == "NamespaceDecl":
            name = node.get("name") or "(anonymous@%s)" % file_here
            for c in node.get("inner", []):
                visit(c, scope + [name], in_function)
            return
        if kind in ("CXXRecordDecl", "ClassTemplateSpecializationDecl") and not in_function:
            qual = "::".join(scope + [node.get("name", "")])
            names[node["id"]] = qual
            for c in node.get("inner", []):
                visit(c, scope + [node.get("name", "")], in_function)
            return
        if kind in FUNCTION_KINDS and node.get("isImplicit"):
            return  # a struct's implicit copy or move: no code of the project's
        if kind in FUNCTION_KINDS and not in_function:
            fscope = scope
            parent = node.get("parentDeclContextId")
            if parent in names:  # an out-of-line member definition
                fscope = names[parent].split("::")
            qual = "::".join(fscope + [node.get("name", "")])
            key = qual + "|" + qual_type_params(node.get("type", {}).get("qualType"))
            first = node.get("previousDecl")
            cid = canonical.get(first, first) if first else node["id"]
            canonical[node["id"]] = cid
            if cid in names and cid != node["id"]:
                key = names[cid]
            names[node["id"]] = key
            names.setdefault(cid, key)
            if any(c.get("kind") == "CompoundStmt" for c in node.get("inner", [])):  # a definition
                calls = []
                for c in node.get("inner", []):
                    visit(c, scope, {"calls": calls})
                defs[key] = {"file": file_here, "calls": calls}
            else:
                for c in node.get("inner", []):
                    visit(c, scope, in_function)
            return
        if in_function:
            ref = None
            if kind == "DeclRefExpr":
                ref = node.get("referencedDecl", {})
                if ref.get("kind") in FUNCTION_KINDS:
                    in_function["calls"].append(("id", ref.get("id"), ref.get("name"),
                                                 qual_type_params(ref.get("type", {}).get("qualType"))))
            elif kind == "MemberExpr":
                mid = node.get("referencedMemberDecl")
                if mid:
                    in_function["calls"].append(("id", mid, node.get("name"), None))
            elif kind == "CXXConstructExpr":
                cls = node.get("type", {}).get("desugaredQualType") or node.get("type", {}).get("qualType", "")
                in_function["calls"].append(("ctor", cls, None, qual_type_params(node.get("ctorType", {}).get("qualType"))))
        for c in node.get("inner", []) if isinstance(node.get("inner"), list) else []:
            visit(c, scope, in_function)

    for r in roots:
        visit(r, [], None)
    # Resolve the calls' decl ids to keys (after the walk: a declaration may follow its use only in
    # another dump, so unresolved ids are dropped: they are not facemorph functions).
    out = {}
    for key, d in defs.items():
        calls = []
        for c in d["calls"]:
            if c[0] == "id":
                cid = canonical.get(c[1], c[1])
                k = names.get(cid) or names.get(c[1])
                if k and "|" in k:
                    calls.append(k)
            else:
                cls = re.sub(r"^(const |struct |class )", "", c[1]).strip()
                name = cls.split("::")[-1]
                if name in CARRIER_SETS["settings"]:
                    calls.append("%s::%s|%s" % (name, name, c[3]))
        out[key] = {"file": d["file"], "calls": list(dict.fromkeys(calls))}
    return out


def is_carrier(key):
    qual, params = key.split("|", 1)
    parts = qual.split("::")
    if len(parts) >= 2 and parts[-2] in CARRIER_CLASSES:
        return True
    return any(re.search(r"\b%s\b" % t, params) for t in CARRIER_TYPES)


def module(path):
    """A header and the source of its name are one file (one module): the source's name."""
    path = os.path.normpath(path)
    if path.endswith(".hpp") and os.path.exists(path[:-4] + ".cpp"):
        return path[:-4] + ".cpp"
    return path


def simple_name(key):
    return key.split("|", 1)[0].split("::")[-1]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--root", default="assemble_parts")
    ap.add_argument("--root-file", default="codec/encoder/encode/staged_encode.cpp")
    ap.add_argument("--build", default="build")
    ap.add_argument("--list", action="store_true", help="print every function with its file")
    ap.add_argument("--carriers", choices=sorted(CARRIER_SETS), default="settings")
    args = ap.parse_args()
    global CARRIER_TYPES
    CARRIER_TYPES = CARRIER_SETS[args.carriers]
    flags = compile_flags(args.build)
    sources = [p for d in SOURCE_DIRS for p in sorted(Path(d).rglob("*.cpp"))]
    texts = {p: p.read_text(errors="replace") for p in sources}
    defs = {}
    parsed = set()

    def parse(path):
        if path in parsed:
            return
        parsed.add(path)
        for k, v in parse_unit(path, flags).items():
            f = module(v["file"])
            # A header's inline definition appears in every unit; a source's own belongs to it.
            if k not in defs or f == module(str(path)):
                defs[k] = {"file": f, "calls": v["calls"]}

    def find(key):
        if key in defs and defs[key]["file"].endswith(".cpp"):
            return defs[key]
        name = simple_name(key)
        pattern = re.compile(r"\b%s\s*\(" % re.escape(name))
        for p in sources:
            if p not in parsed and pattern.search(texts[p]):
                parse(p)
                if key in defs and defs[key]["file"].endswith(".cpp"):
                    break
        return defs.get(key)

    parse(Path(args.root_file))
    roots = [k for k in defs if simple_name(k) == args.root and defs[k]["file"] == module(args.root_file)]
    if not roots:
        sys.exit("options_trace: no definition of %s in %s" % (args.root, args.root_file))
    order, seen, missing = [], set(), set()

    def walk(key):
        seen.add(key)
        d = find(key)
        if d is None:
            missing.add(key)
            return
        order.append((key, d["file"]))
        for callee in d["calls"]:
            if callee not in seen and is_carrier(callee):
                walk(callee)

    sys.setrecursionlimit(10000)
    for r in roots:
        walk(r)
    # Every call between two functions on the path that crosses files enters the callee's file,
    # whichever the walk reached first: the count does not depend on the order of the calls.
    file_of = dict(order)
    entered = {file_of[r]: 1 for r in roots if r in file_of}
    for key, f in order:
        for callee in defs[key]["calls"]:
            if callee in file_of and file_of[callee] != f:
                entered[file_of[callee]] = entered.get(file_of[callee], 0) + 1
    returns = sum(n - 1 for n in entered.values())
    if args.list:
        for key, f in order:
            qual, params = key.split("|", 1)
            print("  %-60s %s" % (qual.replace("facemorph::", "") + "(" + params + ")", f))
        print("files entered (in order of first entry):")
        for f in entered:
            print("  %d  %s" % (entered[f], f))
        if missing:
            # Implicit constructors (a settings struct's copy) have no definition to walk.
            names = sorted(m.split("|")[0] for m in missing)
            print("carriers called without a definition (implicit, not counted): " + ", ".join(names))
    worst = max(entered.items(), key=lambda kv: kv[1])
    print("root %s, carriers %s: %d functions, %d files, %d returns to a file already left; most entered: %s (%d)" %
          (args.root, args.carriers, len(order), len(entered), returns, worst[0], worst[1]))
    if UNPARSED:
        # The counts above miss those files' functions: a figure to report only once they parse.
        sys.exit("options_trace: %d file(s) could not be parsed, so the path above is cut short: %s" % (len(UNPARSED), ", ".join(UNPARSED)))


if __name__ == "__main__":
    main()
