"""The paper's meshes: where `render.py assets` downloads each archive from, its pinned SHA-256
sum, the files the bundled scenes load from it, and its credit and licence (docs/assets.md)."""
from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Archive:
    """One public archive and what the bundled scenes load from it."""
    name: str  # `render.py assets NAME`
    url: str
    sha256: str | None  # of the file at `url`; None: not pinned (downloaded only with trust_unpinned)
    files: tuple[str, ...]  # made by the conversion, relative to the assets folder (a scene's mesh = "...")
    credit: str
    licence: str

    @property
    def filename(self) -> str:
        return self.url.rsplit("/", 1)[-1]

    @property
    def folder(self) -> str:
        return self.files[0].split("/", 1)[0]


ARCHIVES = {a.name: a for a in (
    Archive(
        name="sibenik",
        url="https://casual-effects.com/g3d/data10/research/model/sibenik/sibenik.zip",
        sha256=None,  # no authoritative sum published; docs/assets.md gives the one a third party recorded
        files=("sibenik/sibenik.obj", "sibenik/sibenik_staklo.obj"),
        credit="Sibenik Cathedral by Marko Dabrovic (RNA Studios, www.rna.hr), holes corrected by Kenzie Lamar "
               "(Vicarious Visions), textures by Morgan McGuire; McGuire Computer Graphics Archive",
        licence="the archive's copyright.txt asks for the credit above; McGuire's archive lists the model as "
                "CC BY-NC (docs/assets.md)"),
    Archive(
        name="conference",
        url="https://raw.githubusercontent.com/wahn/rs_pbrt/b675e76614427fa431c666774331b5e17972f72a/assets/"
            "scenes/conference_room.pbrt.gz",
        # the git blob 5a73da95622e6b1cb43d7c4f02a35dd40bf247e0 of that commit, read from the repository
        sha256="af770ffb4e90a2235f81f635fa745d37cc798e42f6a55ec1c8dc19f242ce27c3",
        files=("conference_lbl/conference_lbl.obj", "conference_lbl/conference_lbl.mtl"),
        credit="LBL Building 90 Third Floor Conference Room by Anat Grynberg and Greg Ward (Windows and Lighting "
               "Program, Lawrence Berkeley Laboratory); pbrt export by Jan Walter",
        licence='the model\'s README: "Please do not use this model for any purpose without giving proper credit."'),
)}

# Mesh files of the bundled scenes that no archive provides, and why (the missing-mesh error says it).
NOT_DOWNLOADED = {
    "bridge/bridge_viaduct.glb": "the paper's NVIDIA bridge is not public and the stand-in this scene was made "
                                 "with states no licence, so `render.py assets` does not fetch it "
                                 "(docs/assets.md#the-bridge)",
}
