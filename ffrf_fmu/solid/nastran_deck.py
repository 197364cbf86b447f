"""Where a card sits in a Nastran deck's text: file and line of its first field, following INCLUDEs,
for the error messages of ffrf_fmu/solid/nastran.py (pyNastran keeps no line numbers)."""
from __future__ import annotations

import os
import re


def _bulk_lines(path: str):
    """(file, line number, text) of every bulk data line of the deck, following INCLUDEs."""
    out, in_bulk = [], False
    with open(path, errors="replace") as fh:
        lines = fh.read().splitlines()
    has_bulk = any(ln.upper().startswith("BEGIN BULK") for ln in lines)
    in_bulk = not has_bulk

    def walk(p, lines, bulk):
        for k, text in enumerate(lines, 1):
            u = text.upper()
            if not bulk:
                bulk = u.startswith("BEGIN BULK")
                continue
            m = re.match(r"\s*INCLUDE\s+'([^']+)'", text, re.I)
            if m:
                q = os.path.join(os.path.dirname(p), m.group(1))
                if os.path.exists(q):
                    with open(q, errors="replace") as fh:
                        walk(q, fh.read().splitlines(), True)
                continue
            out.append((p, k, text))
        return bulk

    walk(path, lines, in_bulk)
    return out


def _card_name(text: str) -> str:
    head = text.split(",")[0] if "," in text[:9] else text[:8]
    return head.strip().rstrip("*").upper()


def locate_card(path: str, card: str, card_id=None):
    """First line of card `card` (with id card_id if given) in the deck: 'file:line: text'."""
    for p, k, text in _bulk_lines(path):
        if text.startswith("$") or _card_name(text) != card:
            continue
        if card_id is not None:
            fields = text.split(",") if "," in text else [text[i : i + 8] for i in range(0, 80, 8)]
            if len(fields) < 2 or fields[1].strip() != str(card_id):
                continue
        return f"{p}:{k}: {text.rstrip()}"
    return f"{path}: (card {card} not found in the bulk data text)"
