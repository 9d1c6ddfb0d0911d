"""--set KEY=VALUE for the study scripts (scripts/collision_step,
scripts/friction_cap): dotted scene keys as clothbench.load_scene's
overrides take them, the values parsed as true, false, an integer, a
number or else a word. load_scene validates the keys and values.
"""


def value(text):
    if text in ("true", "false"):
        return text == "true"
    for kind in (int, float):
        try:
            return kind(text)
        except ValueError:
            pass
    return text


def parse(ap, sets):
    """The overrides dict of the --set list `sets`; ap.error on a malformed one."""
    out = {}
    for kv in sets:
        key, sep, text = kv.partition("=")
        if not sep or not key or not text:
            ap.error(f"--set {kv}: must be KEY=VALUE")
        out[key] = value(text)
    return out
