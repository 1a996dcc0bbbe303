#!/usr/bin/env python3
"""Download the upstream (.orig) source tarball of a Debian source package, without root.

Usage: fetch_debian_source.py PACKAGE DEST_DIR STATE_DIR

apt-get runs with a private sources list (deb-src only, Signed-By the Debian
archive keyring), a private lists/cache directory under STATE_DIR and no
system sources.list.d, so nothing on the system is touched and no root is
needed.  apt-get checks the downloaded files against the signed Sources index.

The mirror is the one this machine's own apt configuration uses for the
Debian release (deb822 *.sources or one-line *.list); set KT_DEBIAN_MIRROR to
override it and KT_DEBIAN_SUITE to override the release (default: this
machine's VERSION_CODENAME, else bookworm).

On success prints the path of the .orig tarball (now in DEST_DIR) on the
last line of stdout and exits 0.  Exits non-zero with a message otherwise.
"""
import glob
import os
import shutil
import subprocess
import sys
import tempfile

KEYRING = "/usr/share/keyrings/debian-archive-keyring.gpg"


def die(msg):
    sys.stderr.write("fetch_debian_source: ERROR: " + msg + "\n")
    sys.exit(1)


def codename():
    suite = os.environ.get("KT_DEBIAN_SUITE")
    if suite:
        return suite
    try:
        with open("/etc/os-release") as f:
            for line in f:
                if line.startswith("VERSION_CODENAME="):
                    value = line.split("=", 1)[1].strip().strip('"')
                    if value:
                        return value
    except OSError:
        pass
    return "bookworm"


def deb822_paragraphs(text):
    para, key = {}, None
    for raw in text.splitlines():
        if raw.lstrip().startswith("#"):
            continue
        if not raw.strip():
            if para:
                yield para
            para, key = {}, None
            continue
        if raw[0] in " \t" and key:
            para[key] += " " + raw.strip()
            continue
        if ":" in raw:
            key, value = raw.split(":", 1)
            key = key.strip().lower()
            para[key] = value.strip()
    if para:
        yield para


def system_mirrors(suite):
    """URIs of the system's 'deb' entries that carry SUITE main."""
    found = []
    for path in sorted(glob.glob("/etc/apt/sources.list.d/*.sources")):
        try:
            text = open(path).read()
        except OSError:
            continue
        for p in deb822_paragraphs(text):
            if p.get("enabled", "yes").lower() == "no":
                continue
            if "deb" not in p.get("types", "").split():
                continue
            if suite not in p.get("suites", "").split():
                continue
            if "main" not in p.get("components", "").split():
                continue
            found.extend(p.get("uris", "").split())
    lists = ["/etc/apt/sources.list"] + sorted(glob.glob("/etc/apt/sources.list.d/*.list"))
    for path in lists:
        try:
            lines = open(path).read().splitlines()
        except OSError:
            continue
        for line in lines:
            words = line.split("#", 1)[0].split()
            if len(words) < 4 or words[0] != "deb":
                continue
            if words[1].startswith("["):  # options like [arch=amd64 signed-by=...]
                while words and not words[0].endswith("]"):
                    words.pop(0)
                words.pop(0)
                words.insert(0, "deb")
            if len(words) >= 4 and words[2] == suite and "main" in words[3:]:
                found.append(words[1])
    return found


def main():
    if len(sys.argv) != 4:
        die("usage: fetch_debian_source.py PACKAGE DEST_DIR STATE_DIR")
    package, dest, state = sys.argv[1:]
    if shutil.which("apt-get") is None:
        die("apt-get not found: this needs a Debian-based machine. Put the upstream "
            "tarball of '%s' into %s yourself (or use -DKT_SUNDIALS_TARBALL=...)." % (package, dest))
    if not os.path.isfile(KEYRING):
        die("%s is missing (package debian-archive-keyring)." % KEYRING)
    suite = codename()
    mirrors = [os.environ["KT_DEBIAN_MIRROR"]] if os.environ.get("KT_DEBIAN_MIRROR") else system_mirrors(suite)
    if not mirrors:
        die("no apt 'deb' entry for '%s main' found in /etc/apt; set KT_DEBIAN_MIRROR to a Debian mirror URI." % suite)
    mirror = mirrors[0]

    os.makedirs(dest, exist_ok=True)
    lists = os.path.join(state, "lists")
    cache = os.path.join(state, "cache")
    for d in (os.path.join(lists, "partial"), os.path.join(cache, "archives", "partial")):
        os.makedirs(d, exist_ok=True)
    src_file = os.path.join(state, "src.sources")
    with open(src_file, "w") as f:
        f.write("Types: deb-src\nURIs: %s\nSuites: %s\nComponents: main\nSigned-By: %s\n"
                % (mirror, suite, KEYRING))
    opts = [
        "-o", "Dir::Etc::SourceList=" + src_file,
        "-o", "Dir::Etc::SourceParts=/dev/null",
        "-o", "Dir::State::Lists=" + lists,
        "-o", "Dir::Cache=" + cache,
        "-o", "Debug::NoLocking=1",
    ]
    if os.geteuid() == 0:
        # as root apt would drop to the _apt user, who may not be allowed to write into STATE_DIR
        opts += ["-o", "APT::Sandbox::User=root"]
    print("fetch_debian_source: deb-src %s %s main -> %s" % (mirror, suite, dest), flush=True)
    r = subprocess.run(["apt-get", "-q"] + opts + ["--error-on=any", "update"], stdout=sys.stderr)
    if r.returncode != 0:
        die("'apt-get update' on the private source list failed (exit %d). Is the network to the "
            "Debian mirror up?" % r.returncode)
    work = tempfile.mkdtemp(prefix="dl-", dir=state)
    try:
        r = subprocess.run(["apt-get", "-q"] + opts + ["source", "--download-only", package],
                           cwd=work, stdout=sys.stderr)
        if r.returncode != 0:
            die("'apt-get source --download-only %s' failed (exit %d)." % (package, r.returncode))
        origs = sorted(glob.glob(os.path.join(work, "%s_*.orig.tar.*" % package)))
        origs = [o for o in origs if not o.endswith(".asc")]
        if not origs:
            die("apt-get source ran but no %s_*.orig.tar.* appeared." % package)
        target = os.path.join(dest, os.path.basename(origs[0]))
        shutil.move(origs[0], target + ".part")
        os.replace(target + ".part", target)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    print(target)


if __name__ == "__main__":
    main()
