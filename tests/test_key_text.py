"""The key file's text: pmwm.key.dumps_indent1 writes exactly what json.dumps(..., indent=1) writes."""

import json
import random

import numpy as np

import pmwm
from pmwm.key import dumps_indent1
from meshes import blob


def _document(rng: random.Random, depth: int = 0):
    """A random JSON document: nested dicts and lists, lists (and lists of lists) of numbers, the
    numbers json writes specially, strings with commas and brackets, non-str keys."""
    r = rng.random()
    if depth > 4 or r < 0.3:
        return rng.choice([0, -3, 2**70, 1.5, -0.0, float("nan"), float("inf"), 1e-300, True, None, False,
                           "", "a, b", "], [", 'q"\\', "\u00e9\u2028", np.float64(0.25)])
    if r < 0.5:
        return [rng.choice([1, 2.5, -7, 1e20, float("-inf"), 0.1]) for _ in range(rng.randrange(5))]
    if r < 0.6:
        return [[rng.choice([1, 2.5, -0.0, 10**30]) for _ in range(rng.randrange(3))] for _ in range(rng.randrange(4))]
    if r < 0.8:
        return [_document(rng, depth + 1) for _ in range(rng.randrange(4))]
    return {rng.choice(["k", "a, b", 'x"y', "z", 1, 2.5, None, True]): _document(rng, depth + 1)
            for _ in range(rng.randrange(4))}


def test_dumps_indent1_is_json_dumps_indent1():
    rng = random.Random(0)
    for _ in range(3000):
        doc = _document(rng)
        assert dumps_indent1(doc) == json.dumps(doc, indent=1)


def test_key_file_text_is_json_dumps_indent1():
    V, F = blob()
    key = pmwm.embed(V, F, pmwm.EmbedOptions(seed=3, n_bits=16)).key
    text = key.to_json()
    assert text == json.dumps(json.loads(text), indent=1) + "\n"
