"""Build a terratheme export's landscape material in the Unreal editor (Unreal 5, Python plugin).

Ships in every Unreal export and runs inside the editor (Tools > Execute Python Script,
or ``py "PATH"``), never in terratheme. From ``terratheme_unreal.json`` beside it, it
imports the theme textures and ``colour_map.png`` into ``/Game/Terratheme/<folder>`` and
makes ``M_Terratheme``: a Landscape Layer Blend of one weight-blended layer per theme
(the manifest's ``layers``), each its theme at LandscapeLayerCoords x ``mapping_scale``,
multiplied by the colour map's gain as the renderer does; the result goes to Base Color
(docs/engines.md). Written against Unreal's documented Python API; not run in an Unreal
editor where terratheme is built and tested.
"""

import json
import os
import re

MANIFEST = "terratheme_unreal.json"
MATERIAL = "M_Terratheme"


def _import_textures(unreal, folder, files, destination):
    """Import PNGs of ``folder`` into ``destination``: {file name: texture asset}."""
    tasks = {}
    for name in files:
        task = unreal.AssetImportTask()
        task.set_editor_property("filename", os.path.join(folder, name).replace("\\", "/"))
        task.set_editor_property("destination_path", destination)
        task.set_editor_property("automated", True)
        task.set_editor_property("replace_existing", True)
        task.set_editor_property("save", True)
        tasks[name] = task
    unreal.AssetToolsHelpers.get_asset_tools().import_asset_tasks(list(tasks.values()))
    textures = {}
    for name, task in tasks.items():
        paths = list(task.get_editor_property("imported_object_paths"))
        if not paths:
            raise RuntimeError(os.path.join(folder, name) + ": Unreal did not import it")
        textures[name] = unreal.load_asset(paths[0])
    return textures


def _colour_texture(unreal, texture):
    """Sample the colour map as stored: sRGB, clamped, bilinear, 8 bits uncompressed, one mip."""
    for prop, value in (("srgb", True),
                        ("address_x", unreal.TextureAddress.TA_CLAMP),
                        ("address_y", unreal.TextureAddress.TA_CLAMP),
                        ("compression_settings", unreal.TextureCompressionSettings.TC_EDITOR_ICON),
                        ("mip_gen_settings", unreal.TextureMipGenSettings.TMGS_NO_MIPMAPS),
                        ("filter", unreal.TextureFilter.TF_BILINEAR)):
        texture.set_editor_property(prop, value)
    unreal.EditorAssetLibrary.save_loaded_asset(texture, False)


def build(unreal, folder):
    """Import the export in ``folder`` and make its landscape material; return the material."""
    with open(os.path.join(folder, MANIFEST), encoding="utf-8") as f:
        manifest = json.load(f)
    if manifest.get("format") != "terratheme-unreal":
        raise RuntimeError(os.path.join(folder, MANIFEST) + ": not a terratheme Unreal export")
    base = re.sub(r"[^A-Za-z0-9_]+", "_", os.path.basename(os.path.normpath(folder))) or "export"
    destination = "/Game/Terratheme/" + base
    path = destination + "/" + MATERIAL
    if unreal.EditorAssetLibrary.does_asset_exist(path):
        raise RuntimeError(path + " exists: delete or rename it to build it again")
    layers = manifest["layers"]
    colour = manifest.get("colour_map")
    files = [layer["texture"] for layer in layers] + ([colour["file"]] if colour else [])
    textures = _import_textures(unreal, folder, files, destination)

    mel = unreal.MaterialEditingLibrary
    material = unreal.AssetToolsHelpers.get_asset_tools().create_asset(
        MATERIAL, destination, unreal.Material, unreal.MaterialFactoryNew())

    def node(cls, x, y, **props):
        expression = mel.create_material_expression(material, cls, x, y)
        for prop, value in props.items():
            expression.set_editor_property(prop, value)
        return expression

    def link(source, output, target, input_name):
        if not mel.connect_material_expressions(source, output, target, input_name):
            raise RuntimeError(f"{path}: could not connect {input_name}")

    blend = node(unreal.MaterialExpressionLandscapeLayerBlend, -400, 0)
    inputs = []
    for k, layer in enumerate(layers):
        entry = unreal.LayerBlendInput()
        entry.set_editor_property("layer_name", layer["name"])
        entry.set_editor_property("blend_type", unreal.LandscapeLayerBlendType.LB_WEIGHT_BLEND)
        entry.set_editor_property("preview_weight", 1.0 if k == 0 else 0.0)
        inputs.append(entry)
    blend.set_editor_property("layers", inputs)
    for k, layer in enumerate(layers):
        y = 220 * k
        coords = node(unreal.MaterialExpressionLandscapeLayerCoords, -1100, y,
                      mapping_scale=float(layer["mapping_scale"]))
        sample = node(unreal.MaterialExpressionTextureSample, -800, y,
                      texture=textures[layer["texture"]])
        link(coords, "", sample, "UVs")
        link(sample, "RGB", blend, "Layer " + layer["name"])
    result = blend
    if colour:
        _colour_texture(unreal, textures[colour["file"]])
        y = -400
        coords = node(unreal.MaterialExpressionLandscapeLayerCoords, -1400, y, mapping_scale=1.0)
        (au, av), (bu, bv) = colour["uv_per_vertex"], colour["uv_offset"]
        scale = node(unreal.MaterialExpressionConstant2Vector, -1400, y + 120, r=au, g=av)
        offset = node(unreal.MaterialExpressionConstant2Vector, -1400, y + 240, r=bu, g=bv)
        scaled = node(unreal.MaterialExpressionMultiply, -1150, y)
        link(coords, "", scaled, "A")
        link(scale, "", scaled, "B")
        uv = node(unreal.MaterialExpressionAdd, -1000, y)
        link(scaled, "", uv, "A")
        link(offset, "", uv, "B")
        sample = node(unreal.MaterialExpressionTextureSample, -800, y,
                      texture=textures[colour["file"]])
        link(uv, "", sample, "UVs")
        gain = node(unreal.MaterialExpressionMultiply, -500, y,
                    const_b=float(colour["linear_gain"]))
        link(sample, "RGB", gain, "A")
        result = node(unreal.MaterialExpressionMultiply, -200, 0)
        link(blend, "", result, "A")
        link(gain, "", result, "B")
    if not mel.connect_material_property(result, "", unreal.MaterialProperty.MP_BASE_COLOR):
        raise RuntimeError(path + ": could not connect Base Color")
    mel.recompile_material(material)
    unreal.EditorAssetLibrary.save_loaded_asset(material, False)
    unreal.log(f"{path}: {len(layers)} layers"
               + (", times the colour map" if colour else "") + " (terratheme)")
    return material


def main():
    """Build the material of the export this file sits in."""
    import unreal

    build(unreal, os.path.dirname(os.path.abspath(__file__)))


if __name__ == "__main__":
    main()
