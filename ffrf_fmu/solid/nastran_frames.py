"""GRID displacement frames (CD) of a Nastran deck (ffrf_fmu/solid/nastran.py; docs/nastran.md).

Nastran gives a GRID's six dofs in its displacement frame CD (translations T1 T2 T3 and rotations
R1 R2 R3 along the axes of CD at the GRID, for CORD2C/CORD2S the local r, theta, z or r, theta, phi
there). Here every GRID's dofs are in the basic frame: K and M are assembled in the basic frame
whatever the CD (the element matrices never saw the CD frames), which is the deck's model after the
transformation u_CD = R^T u_basic of each node (the same eigenvalues; R orthogonal). What a frame
changes is the meaning of component lists on that GRID: an SPC/SPC1, an RBE2's CM on its dependent
GRIDs, an RBE3's REFC. A list holding all three translations, all three rotations, both or neither
is the same set of constraints in any frame; any other list (e.g. SPC 3 on a GRID of a cylindrical
CD: a radial constraint) would be a constraint along a turned axis, and is refused, naming the card.
"""
from __future__ import annotations


def _invariant(components) -> bool:
    c = {int(ch) for ch in str(components) if ch not in "0 "}
    return all(len(c & part) in (0, 3) for part in ({1, 2, 3}, {4, 5, 6}))


def check_displacement_frames(refuse, model) -> dict:
    """{GRID id: CD} of the GRIDs with CD != 0, after checking that every component list on them is
    frame-invariant (module doc); refuse(card, id, why) raises."""
    cd = {int(nid): int(node.cd) for nid, node in model.nodes.items() if node.cd not in (0, None)}
    if not cd:
        return cd

    def check(card, card_id, grid, components):
        if int(grid) in cd and not _invariant(components):
            refuse(card, card_id, f"components {components} on GRID {grid}, whose displacement frame is "
                   f"CD = {cd[int(grid)]}: only 123, 456 or 123456 there (frame-invariant; dofs are in the basic frame)")

    for sid, cards in model.spcs.items():
        for card in cards:
            if card.type == "SPC":
                for g, comp in zip(card.nodes, card.components):
                    check("SPC", sid, g, comp)
            elif card.type == "SPC1":
                for g in card.nodes:
                    check("SPC1", sid, g, card.components)
    for eid, elem in model.rigid_elements.items():
        if elem.type == "RBE2":
            for g in elem.Gmi:
                check("RBE2", eid, g, elem.cm)
        elif elem.type == "RBE3":
            check("RBE3", eid, elem.refgrid, elem.refc)
    return cd
