"""What scripts/cueing-bars.py and scripts/tune-acceptance.py share: a profile with the
solvers' wall-clock limit lifted (as `hexcue compare` and `hexcue tune` do, so that a result
does not depend on the machine's load), and one headless run's JSON summary."""
import json
import os
import re
import subprocess
import sys


def unlimited_profile(profile, folder, name):
    """A copy of `profile` in `folder`, as NAME.toml, with `time_limit_ms = 1e9`."""
    with open(profile) as f:
        text = f.read()
    text, n = re.subn(r"(?m)^time_limit_ms\s*=.*$", "time_limit_ms = 1e9", text)
    if n != 1:
        sys.exit(f"{profile}: expected one time_limit_ms line, found {n}")
    path = os.path.join(folder, name + ".toml")
    with open(path, "w") as f:
        f.write(text)
    return path


def play_summary(hexcue, profile, trace, out):
    """`hexcue play --headless` of every algorithm on `trace`; its summary as a dict."""
    subprocess.run([hexcue, "play", "--headless", "--trace", trace, "--profile", profile,
                    "--summary", out, "--force"], check=True, stdout=subprocess.DEVNULL)
    with open(out) as f:
        return json.load(f)
