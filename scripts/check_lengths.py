#!/usr/bin/env python3
"""check_lengths.py: the size limits of the project's own code, src/ and kernels/ (tests aside).

A file holds at most 500 lines and a function at most 80. A function is found by its body: a line
that opens a brace block at nesting depth 0 (or at depth 1 inside a namespace) after a signature,
closed by the matching brace; its length counts the signature's first line through the closing
brace. Braces inside strings, character literals and comments are skipped. Prints every offender
as path:line and exits 1 when there is one.

    scripts/check_lengths.py [repository root]
    scripts/check_lengths.py --self-test   (a file of 501 lines and a function of 81 must fail,
                                            a function of 80 must pass)
"""
import os
import re
import sys
import tempfile

MAX_FILE = 500
MAX_FUNCTION = 80
SUFFIXES = (".h", ".cpp", ".cl", ".hpp")


def strip(text):
    """The text with comments, strings and character literals blanked (newlines kept)."""
    out, i, n = [], 0, len(text)
    while i < n:
        c = text[i]
        if text.startswith("//", i):
            j = text.find("\n", i)
            j = n if j < 0 else j
            i = j
        elif text.startswith("/*", i):
            j = text.find("*/", i + 2)
            j = n if j < 0 else j + 2
            out.append("\n" * text.count("\n", i, j))
            i = j
        elif text.startswith('R"', i) and (i == 0 or not (text[i - 1].isalnum() or text[i - 1] == "_")):
            m = re.match(r'R"([^(\s]*)\(', text[i:])
            if not m:
                out.append(c)
                i += 1
                continue
            end = ")" + m.group(1) + '"'
            j = text.find(end, i + m.end())
            j = n if j < 0 else j + len(end)
            out.append('""' + "\n" * text.count("\n", i, j))
            i = j
        elif c in "\"'":
            j = i + 1
            while j < n and text[j] != c and text[j] != "\n":
                j += 2 if text[j] == "\\" else 1
            out.append(c + c)
            i = j + 1
        else:
            out.append(c)
            i += 1
    return "".join(out)


def functions(text):
    """(first line, length) of each function body in text."""
    code = strip(text)
    lines = code.split("\n")
    found, stack = [], []  # stack of (kind, start line)
    for ln, line in enumerate(lines):
        for col, ch in enumerate(line):
            if ch == "{":
                head = line[:col].strip()
                prev = ln
                while not head and prev > 0:  # brace alone on its line: the signature is above
                    prev -= 1
                    head = lines[prev].strip()
                in_scope = all(k == "ns" for k, _ in stack)
                if re.match(r"^(namespace|extern\s+\"\")", head) or re.search(r"\bnamespace\b[\w:\s]*$", head):
                    kind = "ns"
                elif in_scope and re.search(r"\)\s*(const|noexcept|override|final|->\s*[\w:<>]+|\s)*$", head) \
                        and not re.match(r"^(if|for|while|switch|else|do)\b", head):
                    kind = "fn"
                elif in_scope and re.match(r"^(struct|class|union|enum)\b", head) or head.startswith("template"):
                    kind = "ns" if re.match(r"^(struct|class|union)\b", head) else "other"
                else:
                    kind = "other"
                start = ln
                while start > 0 and lines[start - 1].strip() and not re.search(r"[;{}]\s*$", lines[start - 1]) \
                        and not lines[start - 1].lstrip().startswith("#") and kind == "fn":
                    start -= 1
                stack.append((kind, start))
            elif ch == "}" and stack:
                kind, start = stack.pop()
                if kind == "fn":
                    found.append((start + 1, ln - start + 1))
    return found


def self_test():
    """The checker on made-up files: it must flag what is over the limits and nothing else."""
    body = lambda n: "int f() {\n" + "  x();\n" * (n - 2) + "}\n"
    ok = [length for _, length in functions(body(80))] == [80]
    ok &= [length for _, length in functions("namespace a {\n" + body(81) + "}\n")] == [81]
    ok &= [length for _, length in functions("struct S {\n  void g() {\n  }\n};\n/* { */ const char* s = \"{\";\n")] == [2]
    with tempfile.TemporaryDirectory() as d:
        os.makedirs(os.path.join(d, "src"))
        os.makedirs(os.path.join(d, "kernels"))
        with open(os.path.join(d, "kernels", "big.h"), "w") as f:
            f.write("/* */\n" * 501)
        ok &= check(d) == ["kernels/big.h:1: file of 501 lines (limit 500)"]
    print("self-test " + ("passed" if ok else "FAILED"))
    return 0 if ok else 1


def check(root):
    bad = []
    for top in ("src", "kernels"):
        for dirpath, _, names in os.walk(os.path.join(root, top)):
            for name in sorted(names):
                if not name.endswith(SUFFIXES):
                    continue
                path = os.path.join(dirpath, name)
                rel = os.path.relpath(path, root)
                with open(path, encoding="utf-8", errors="replace") as f:
                    text = f.read()
                n = text.count("\n")
                if n > MAX_FILE:
                    bad.append(f"{rel}:1: file of {n} lines (limit {MAX_FILE})")
                for line, length in functions(text):
                    if length > MAX_FUNCTION:
                        bad.append(f"{rel}:{line}: function of {length} lines (limit {MAX_FUNCTION})")
    return sorted(bad)


def main():
    if len(sys.argv) > 1 and sys.argv[1] == "--self-test":
        return self_test()
    root = sys.argv[1] if len(sys.argv) > 1 else os.path.join(os.path.dirname(__file__), "..")
    bad = check(root)
    for b in bad:
        print(b)
    if bad:
        print(f"{len(bad)} over the limits", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
