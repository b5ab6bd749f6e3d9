#!/usr/bin/env python3
"""docs_test: the documentation against the build it describes.

    docs_test.py --source REPOSITORY --build BUILD_FOLDER

Checks, for README.md, docs/*.md and deploy/README-farm.md:

  paths   every word of a shell block (```sh, ```bash, ```shell) that names a path of the
          build (build/..., ./build/...) exists in BUILD (build/ read as BUILD/), and every
          word that names a repository path (deploy/, tests/, core/, ..., ../shared/ when
          that folder is there) exists in the source tree; a program of build/bin named
          anywhere else under build/ is an error. Placeholders (FILE, SCENE, <...>), words
          with globs or variables, and what the command itself writes (after --out, -o, >,
          --data, --cache, --dir, --save, --address-file, ...) are not required.
  inline  the same for inline code in the prose that starts with a build path
          (`build/bin/bench_bake ...`);
  links   every Markdown link and image with a relative target resolves to a file or
          folder (an anchor after # is not checked).

then runs, in a temporary folder and each under a timeout, asserting exit status 0 and
the output's content:

  help    --help of build/bin/cpvs, cpvs-server, cpvs-worker and of every cpvs
          subcommand that `cpvs --help` lists (and their own subcommands);
  sun     the `cpvs sun` example as the documentation writes it (a direction, an
          elevation);
  bake    a 1K bake of the city, and `cpvs inspect` of it (resolution 1024);

and checks deploy/Dockerfile:

  docker  every COPY source (not --from) exists in the repository; every path under
          /build/ or /out/bin (the build's folder and `cmake --install`'s prefix there)
          maps to a file of BUILD, and the program the image runs is one of build/bin.

One `ok:` line per group; every failure with its file and line; exit 1 on any failure.
Python's standard library only.
"""

import argparse
import glob
import os
import re
import shlex
import subprocess
import sys
import tempfile

SHELL_INFO = {"sh", "bash", "shell", "console"}
REPO_PREFIXES = ("deploy/", "tests/", "core/", "runtime/", "server/", "worker/", "client/", "eval/", "net/",
                 "proto/", "docs/", ".ci/")
# Options whose value is what the command writes, not something that must exist already.
PRODUCT_OPTIONS = {"--out", "-o", "--data", "--cache", "--dir", "--save", "--address-file", "--coverage-png",
                   "--animation", "--prefix", "-keyout", "-out"}
REDIRECTIONS = {">", ">>", "&>", ">|", "2>", "1>"}
# Folders a repository script writes: a path under one is accepted when the script is there.
GENERATED = {
    "deploy/secrets/": "deploy/make-secrets.sh",
    "build/fuzz/": "tests/fuzz/run.sh",
}
# All-capitals names that are real files, not placeholders.
REAL_CAPITALS = {"README", "LICENSE", "COPYING", "COPYRIGHT", "NOTICE", "AUTHORS", "CHANGELOG", "DESIGN"}


class Report:
    def __init__(self):
        self.failures = 0

    def fail(self, where, message):
        self.failures += 1
        print(f"FAIL: {where}: {message}")

    def group(self, name, failures_before, detail):
        if self.failures == failures_before:
            print(f"ok: {name}: {detail}")
        else:
            print(f"FAIL: {name}: {self.failures - failures_before} failure(s)")


# ---------------------------------------------------------------------------------------
# Markdown

def doc_files(source):
    files = [os.path.join(source, "README.md")]
    files += sorted(glob.glob(os.path.join(source, "docs", "*.md")))
    farm = os.path.join(source, "deploy", "README-farm.md")
    if os.path.exists(farm):
        files.append(farm)
    return files


FENCE = re.compile(r"^(\s*)(`{3,}|~{3,})\s*([^\s`]*)")


def fenced_blocks(lines):
    """(info string, [(line number, text)]) for every fenced block."""
    blocks, current, fence, info = [], None, None, None
    for number, line in enumerate(lines, 1):
        m = FENCE.match(line)
        if current is None:
            if m:
                fence, info, current = m.group(2), m.group(3).lower(), []
        elif m and m.group(2).startswith(fence[0]) and len(m.group(2)) >= len(fence) and not m.group(3):
            blocks.append((info, current))
            current = None
        else:
            current.append((number, line))
    return blocks


def prose_lines(lines, keep_code=False):
    """The lines outside fenced blocks (fenced lines blank), inline code spans blanked out
    unless keep_code."""
    inside, fence = False, None
    out = []
    for number, line in enumerate(lines, 1):
        m = FENCE.match(line)
        if not inside and m:
            inside, fence = True, m.group(2)
            out.append((number, ""))
            continue
        if inside:
            if m and m.group(2).startswith(fence[0]) and len(m.group(2)) >= len(fence) and not m.group(3):
                inside = False
            out.append((number, ""))
            continue
        out.append((number, line if keep_code else re.sub(r"`[^`]*`", lambda s: " " * len(s.group(0)), line)))
    return out


def line_of(starts, position):
    """The 1-based line holding a character offset, from each line's starting offset."""
    low, high = 0, len(starts) - 1
    while low < high:
        middle = (low + high + 1) // 2
        if starts[middle] <= position:
            low = middle
        else:
            high = middle - 1
    return low + 1


def joined(prose):
    text = "\n".join(t for _, t in prose)
    starts, offset = [], 0
    for _, t in prose:
        starts.append(offset)
        offset += len(t) + 1
    return text, starts


def logical_commands(block_lines):
    """Joins lines ending in a backslash: [(first line number, [(line number, text)])]."""
    commands, pending = [], []
    for number, text in block_lines:
        pending.append((number, text))
        if not text.rstrip().endswith("\\"):
            commands.append(pending)
            pending = []
    if pending:
        commands.append(pending)
    return commands


def words_of(text):
    """Shell words of one line, with operators as words of their own; comments dropped."""
    lexer = shlex.shlex(text, posix=True, punctuation_chars=True)
    lexer.whitespace_split = True
    lexer.commenters = "#"
    try:
        return list(lexer)
    except ValueError:  # an unbalanced quote on a continued line: plain words
        return text.split("#", 1)[0].split()


def is_placeholder(word):
    if re.search(r"[*?\[\]{}$<>~`|]|\.\.\.|…", word):
        return True
    for part in word.split("/"):
        stem = part.split(".", 1)[0]
        if re.fullmatch(r"[A-Z][A-Z0-9_]+", stem) and stem not in REAL_CAPITALS:
            return True
    return False


def path_candidate(word):
    """The path a word names, if any: the value after the last '=' of --opt=v or K=v."""
    if "=" in word:
        word = word.rsplit("=", 1)[1]
    word = word.strip(",;")
    return word


def check_shell_paths(source, build, report):
    shared = os.path.isdir(os.path.join(source, "..", "shared"))
    bin_programs = set(os.listdir(os.path.join(build, "bin")))
    checked = 0
    for path in doc_files(source):
        rel = os.path.relpath(path, source)
        lines = open(path, encoding="utf-8").read().split("\n")
        for info, block in fenced_blocks(lines):
            if info not in SHELL_INFO:
                continue
            for command in logical_commands(block):
                previous = None
                for number, text in command:
                    text = text.rstrip()
                    if text.endswith("\\"):
                        text = text[:-1]
                    for word in words_of(text):
                        product = previous in PRODUCT_OPTIONS or previous in REDIRECTIONS
                        option = word.split("=", 1)[0] if word.startswith("-") and "=" in word else None
                        previous = word
                        if product or option in PRODUCT_OPTIONS:
                            continue
                        candidate = path_candidate(word)
                        where = f"{rel}:{number}"
                        if candidate.startswith("./"):
                            candidate = candidate[2:]
                        if candidate.startswith("build/"):
                            if is_placeholder(candidate):
                                continue
                            checked += 1
                            check_build_path(candidate, build, bin_programs, source, where, report)
                        elif candidate.startswith(REPO_PREFIXES) or (shared and candidate.startswith("../shared/")):
                            if is_placeholder(candidate):
                                continue
                            checked += 1
                            check_source_path(candidate, source, where, report)
    return checked


def check_inline_build_paths(source, build, report):
    """Inline code in the prose that starts with a path of the build (`build/bin/bench_bake`)."""
    bin_programs = set(os.listdir(os.path.join(build, "bin")))
    checked = 0
    for path in doc_files(source):
        rel = os.path.relpath(path, source)
        lines = open(path, encoding="utf-8").read().split("\n")
        text, starts = joined(prose_lines(lines, keep_code=True))
        for m in re.finditer(r"`([^`]+)`", text):
            words = m.group(1).split()
            if not words:
                continue
            candidate = words[0][2:] if words[0].startswith("./") else words[0]
            if not candidate.startswith("build/") or is_placeholder(candidate):
                continue
            checked += 1
            check_build_path(candidate, build, bin_programs, source, f"{rel}:{line_of(starts, m.start())}", report)
    return checked


def generated_by(candidate, source):
    for prefix, script in GENERATED.items():
        if (candidate.rstrip("/") + "/").startswith(prefix) and os.path.exists(os.path.join(source, script)):
            return script
    return None


def check_build_path(candidate, build, bin_programs, source, where, report):
    inner = candidate[len("build/"):].rstrip("/")
    name = os.path.basename(inner)
    if name in bin_programs and os.path.dirname(inner) != "bin":
        report.fail(where, f"{candidate}: the programs are in build/bin (build/bin/{name})")
        return
    if generated_by(candidate, source):
        return
    if not os.path.exists(os.path.join(build, inner)):
        report.fail(where, f"{candidate} does not exist in the build ({os.path.join(build, inner)})")


def check_source_path(candidate, source, where, report):
    if generated_by(candidate, source):
        return
    if not os.path.exists(os.path.join(source, candidate.rstrip("/"))):
        report.fail(where, f"{candidate} does not exist in the repository")


LINK = re.compile(r"!?\[(?:[^\[\]]|\[[^\[\]]*\])*\]\(\s*<?([^)\s>]+)>?(?:\s+\"[^\"]*\")?\s*\)")
REFERENCE = re.compile(r"^\s{0,3}\[[^\]]+\]:\s*<?(\S+?)>?(?:\s.*)?$")


def check_links(source, report):
    checked = 0
    for path in doc_files(source):
        rel = os.path.relpath(path, source)
        lines = open(path, encoding="utf-8").read().split("\n")
        prose = prose_lines(lines)
        text, starts = joined(prose)
        targets = [(m.start(), m.group(1)) for m in LINK.finditer(text)]
        for i, (_, t) in enumerate(prose):
            m = REFERENCE.match(t)
            if m:
                targets.append((starts[i], m.group(1)))
        for position, target in targets:
            number = line_of(starts, position)
            if re.match(r"^[a-zA-Z][a-zA-Z0-9+.-]*:", target) or target.startswith("#"):
                continue  # a URL, mailto:, or an anchor of the same page
            file_part = target.split("#", 1)[0].split("?", 1)[0]
            if not file_part:
                continue
            checked += 1
            resolved = os.path.normpath(os.path.join(os.path.dirname(path), file_part))
            if not os.path.exists(resolved):
                report.fail(f"{rel}:{number}", f"link or image {target} does not resolve ({resolved})")
    return checked


# ---------------------------------------------------------------------------------------
# Commands

def run(argv, cwd, timeout):
    try:
        p = subprocess.run(argv, cwd=cwd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, timeout=timeout)
        return p.returncode, p.stdout.decode("utf-8", "replace")
    except subprocess.TimeoutExpired as e:
        out = (e.stdout or b"").decode("utf-8", "replace")
        return None, out + f"\n(timed out after {timeout} s)"
    except OSError as e:
        return None, str(e)


def subcommands(help_text):
    """The names a CLI11 help lists under 'Subcommands:'."""
    names, inside = [], False
    for line in help_text.split("\n"):
        if re.match(r"^subcommands:\s*$", line.strip(), re.IGNORECASE):
            inside = True
            continue
        if inside:
            m = re.match(r"^  ([a-z][a-z0-9-]*)(\s|$)", line)
            if m:
                names.append(m.group(1))
            elif line.strip() and not line.startswith("    "):
                inside = False
    return names


def tail(text, lines=15):
    return "\n".join("      " + l for l in text.rstrip().split("\n")[-lines:])


def check_help(build, tmp, report):
    cpvs = os.path.join(build, "bin", "cpvs")
    checked = 0
    expect = {"cpvs": "Subcommands:", "cpvs-server": "--listen", "cpvs-worker": "--server"}
    top = ""
    for program, needle in expect.items():
        checked += 1
        status, out = run([os.path.join(build, "bin", program), "--help"], tmp, 30)
        if status != 0 or needle not in out or "Usage" not in out:
            report.fail(f"build/bin/{program} --help", f"exit {status}, expected 'Usage' and '{needle}':\n{tail(out)}")
        if program == "cpvs":
            top = out
    names = subcommands(top)
    if len(names) < 5:
        report.fail("build/bin/cpvs --help", f"lists {len(names)} subcommands: {names}")
    pending = [[n] for n in names]
    while pending:
        path = pending.pop(0)
        checked += 1
        status, out = run([cpvs] + path + ["--help"], tmp, 30)
        label = "cpvs " + " ".join(path) + " --help"
        if status != 0 or "Usage" not in out or " ".join(path) not in out:
            report.fail(label, f"exit {status}, expected its usage line:\n{tail(out)}")
            continue
        if "--help" not in out or len(out.strip().split("\n")) < 3:
            report.fail(label, f"prints no options:\n{tail(out)}")
        pending += [path + [s] for s in subcommands(out)]
    return checked, len(names)


def sun_examples(source):
    """Fenced lines that run `cpvs sun` as written: [(file:line, argv after 'sun')]."""
    found = []
    for path in doc_files(source):
        rel = os.path.relpath(path, source)
        lines = open(path, encoding="utf-8").read().split("\n")
        for _, block in fenced_blocks(lines):
            for command in logical_commands(block):
                text = " ".join(t.rstrip().rstrip("\\") for _, t in command).strip()
                m = re.match(r"^(?:\./)?(?:build/bin/)?cpvs\s+sun(\s.*)?$", text)
                if not m:
                    continue
                words = words_of(text)
                if any(is_placeholder(w) or w.startswith("[") for w in words):
                    continue  # a synopsis (--lat DEG), not an example
                found.append((f"{rel}:{command[0][0]}", words[2:]))
    return found


def check_sun(source, build, tmp, report):
    examples = sun_examples(source)
    if not examples:
        report.fail("docs", "no fenced `cpvs sun ...` example to run (README.md or docs/)")
        return 0
    for where, args in examples:
        status, out = run([os.path.join(build, "bin", "cpvs"), "sun"] + args, tmp, 30)
        ok = status == 0 and (re.search(r"elevation -?\d+\.\d+ deg", out) or '"elevation_deg"' in out)
        ok = ok and (re.search(r"-?\d+\.\d+,-?\d+\.\d+,-?\d+\.\d+", out) or "night" in out)
        if not ok:
            report.fail(where, f"cpvs sun {' '.join(args)}: exit {status}, expected an elevation and a "
                               f"direction:\n{tail(out)}")
    return len(examples)


def check_bake(build, tmp, report):
    cpvs = os.path.join(build, "bin", "cpvs")
    out_file = os.path.join(tmp, "city.cpvs")
    argv = [cpvs, "bake", "city", "--sun-elevation", "35", "--sun-azimuth", "30", "--resolution", "1K",
            "--out", out_file]
    status, out = run(argv, tmp, 300)
    if status != 0 or not os.path.isfile(out_file) or os.path.getsize(out_file) == 0:
        report.fail("cpvs bake city ... --resolution 1K", f"exit {status}, file written: "
                                                           f"{os.path.isfile(out_file)}:\n{tail(out)}")
        return
    status, out = run([cpvs, "inspect", out_file], tmp, 60)
    if status != 0 or not re.search(r"resolution\s+1024\b", out):
        report.fail("cpvs inspect city.cpvs", f"exit {status}, expected 'resolution 1024':\n{tail(out)}")


# ---------------------------------------------------------------------------------------
# Dockerfile

def dockerfile_instructions(path):
    """[(line number, instruction, arguments)] with continuations joined, comments dropped."""
    out, pending, first = [], "", None
    for number, line in enumerate(open(path, encoding="utf-8").read().split("\n"), 1):
        stripped = line.strip()
        if not pending and (not stripped or stripped.startswith("#")):
            continue
        if pending and stripped.startswith("#"):
            continue
        if not pending:
            first = number
        if stripped.endswith("\\"):
            pending += stripped[:-1] + " "
            continue
        pending += stripped
        parts = pending.split(None, 1)
        out.append((first, parts[0].upper(), parts[1] if len(parts) > 1 else ""))
        pending = ""
    return out


def check_dockerfile(source, build, report):
    path = os.path.join(source, "deploy", "Dockerfile")
    rel = os.path.relpath(path, source)
    if not os.path.exists(path):
        report.fail(rel, "does not exist")
        return 0
    checked = 0
    bin_dir = os.path.join(build, "bin")
    for number, instruction, args in dockerfile_instructions(path):
        where = f"{rel}:{number}"
        if instruction in ("COPY", "ADD"):
            if args.startswith("["):
                import json
                words = json.loads(args)
            else:
                words = shlex.split(args)
            flags = [w for w in words if w.startswith("--")]
            paths = [w for w in words if not w.startswith("--")]
            if not any(f.startswith("--from") for f in flags):
                for src in paths[:-1]:
                    checked += 1
                    if not glob.glob(os.path.join(source, src)):
                        report.fail(where, f"COPY source {src} does not exist in the repository")
        if instruction in ("CMD", "ENTRYPOINT") and args.startswith("["):
            import json
            program = json.loads(args)[0]
            if "/" not in program:
                checked += 1
                if not os.path.exists(os.path.join(bin_dir, program)):
                    report.fail(where, f"{instruction} runs {program}, which build/bin does not have")
    # Paths of the build stage's build folder (/build) and install prefix (/out), comments too.
    for number, line in enumerate(open(path, encoding="utf-8").read().split("\n"), 1):
        for m in BUILD_STAGE_PATH.finditer(line):
            named = m.group(1).rstrip(",.")
            if named.startswith("/build/"):
                mapped = os.path.join(build, named[len("/build/"):])
            else:  # /out is `cmake --install`'s prefix: its bin/ is what build/bin holds
                mapped = os.path.join(bin_dir, named[len("/out/bin"):].lstrip("/"))
            checked += 1
            if not os.path.exists(mapped.rstrip("/")):
                report.fail(f"{rel}:{number}", f"{named} maps to {mapped}, which the build does not have")
    return checked


BUILD_STAGE_PATH = re.compile(r"(?<![\w.])(/build/[^\s\"';&|)\]]+|/out/bin(?![\w-])(?:/[^\s\"';&|)\]]*)?)")


# ---------------------------------------------------------------------------------------

def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--source", required=True, help="the repository")
    parser.add_argument("--build", required=True, help="the build folder (build/ in the documentation)")
    a = parser.parse_args()
    source, build = os.path.abspath(a.source), os.path.abspath(a.build)
    report = Report()
    if not os.path.isfile(os.path.join(build, "bin", "cpvs")):
        report.fail("build", f"{os.path.join(build, 'bin', 'cpvs')} does not exist: build the project first "
                             "(bash deploy/build.sh), then run this test on that build")
        return 1

    before = report.failures
    n = check_shell_paths(source, build, report)
    report.group("paths", before, f"{n} paths named in shell blocks of {len(doc_files(source))} files exist")

    before = report.failures
    n = check_inline_build_paths(source, build, report)
    report.group("inline build paths", before, f"{n} paths of the build named in inline code exist")

    before = report.failures
    n = check_links(source, report)
    report.group("links", before, f"{n} relative links and images resolve")

    with tempfile.TemporaryDirectory(prefix="docs_test-") as tmp:
        before = report.failures
        n, subs = check_help(build, tmp, report)
        report.group("help", before, f"--help of {n} programs and subcommands ({subs} cpvs subcommands)")

        before = report.failures
        n = check_sun(source, build, tmp, report)
        report.group("sun", before, f"{n} documented `cpvs sun` example(s) give a direction and an elevation")

        before = report.failures
        check_bake(build, tmp, report)
        report.group("bake", before, "cpvs bake city at 1K wrote its file; cpvs inspect shows resolution 1024")

    before = report.failures
    n = check_dockerfile(source, build, report)
    report.group("docker", before, f"deploy/Dockerfile: {n} COPY sources and build paths exist")

    if report.failures:
        print(f"docs_test: {report.failures} failure(s)")
        return 1
    print("docs_test: all checks passed")
    return 0


if __name__ == "__main__":
    sys.exit(main())
