"""Finds citations of the issue tracker by number in the project's sources, tests, docs and scripts.

A number means nothing to a reader without the tracker, and trackers move: a comment or a doc says
in words what it is about, and the history (commit messages) keeps the links. Counted as a
citation (N a number, any case):
- a tracker word and the number: "issue N", "issues #N", "Issue N's", "task N", "ticket #N", and
  with the hash only, "bug #N", "PR #N", "pull request #N", "MR #N";
- a tracker link or short form: ".../issues/N", ".../pull/N", "GH-N";
- a bare "#N" where people cite a tracker: in brackets "(#N)", "[#N]", after "see", "fixes",
  "closes", "resolves", "refs", "cf." or "per", or opening a comment ("// #N: ...").
Not counted: #include and other directives, colours (CSS's #000), anchors (#3-a-title),
"frame #3", "#1" inside data.
"""
import os
import re

KEYWORD = re.compile(r'\b(?:issues?|tasks?|tickets?)\s*(?:no\.\s*)?#?\d+(?![\w-])'
                     r'|\b(?:bugs?|PRs?|pull\s+requests?|merge\s+requests?|MRs?)\s*#\d+(?![\w-])'
                     r'|/(?:issues|pull|pulls|merge_requests)/\d+\b'
                     r'|\bGH-\d+\b', re.IGNORECASE)
BARE_HASH = re.compile(r'(?:[(\[]|\b(?:see|fix|fixe[sd]|close[sd]?|resolve[sd]?|refs?|cf\.|per)\s+'
                       r'|(?:^|\s)(?://|/\*|\*|#|<!--|--)\s*)#\d+(?![\w-])', re.IGNORECASE | re.MULTILINE)

TEXT_SUFFIXES = (".cpp", ".h", ".hpp", ".cc", ".c", ".py", ".sh", ".md", ".txt", ".cmake", ".yaml", ".yml",
                 ".proto", ".js", ".html", ".css", ".sbatch", ".pov", ".toml", ".cfg", ".in")
TEXT_NAMES = ("Dockerfile", "CMakeLists.txt")
# Build folders, version control, caches and fuzz corpora (inputs, not prose).
SKIPPED_DIRS = ("corpus", "__pycache__", "node_modules")


def is_text_source(path):
    name = os.path.basename(path)
    if name.endswith(TEXT_SUFFIXES) or name.startswith(TEXT_NAMES):
        return True
    if "." in name:
        return False
    try:  # an extensionless script (.ci/run)
        with open(path, "rb") as f:
            return f.read(2) == b"#!"
    except OSError:
        return False


def source_files(src):
    """The project's text files under `src`, relative to it."""
    for root, dirs, files in os.walk(src):
        dirs[:] = sorted(d for d in dirs if d not in SKIPPED_DIRS and not d.startswith("build")
                         and (not d.startswith(".") or d == ".ci"))
        for f in sorted(files):
            path = os.path.join(root, f)
            if is_text_source(path):
                yield os.path.relpath(path, src)


def tracker_citations(src):
    """One line per citation: FILE:LINE and what was found."""
    found = []
    for rel in source_files(src):
        with open(os.path.join(src, rel), encoding="utf-8", errors="replace") as f:
            text = f.read()
        for pattern in (KEYWORD, BARE_HASH):
            for m in pattern.finditer(text):
                line = text.count("\n", 0, m.start()) + 1
                found.append(f"{rel}:{line}: cites the tracker by number ({m.group(0).strip()!r}): "
                             "say in words what it is about")
    return found
