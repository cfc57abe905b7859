// Terratheme colour map for the Unity terrain shaders of a terratheme export (docs/engines.md).
//
// terratheme multiplies every texel of the blended themes by the colour map's gain value / 128
// per channel (neutral 128). Unity decodes colour_map.png (an sRGB texture) to linear before the
// multiply, so the decoded sample is scaled by _ColourGain: 1 / srgb_to_linear(128 / 255) = 4.633
// in a Linear colour space project (neutral 128 gives exactly 1), 255 / 128 in Gamma; the
// importer sets it. _ColourMap_ST is the tile's colour_map_st from terratheme_unity.json:
// texture UV = terrain UV * xy + zw, so a bilinear sample is the renderer's gain at every texel.
#ifndef TERRATHEME_COLOUR_MAP_INCLUDED
#define TERRATHEME_COLOUR_MAP_INCLUDED

sampler2D _ColourMap;
float4 _ColourMap_ST;
float _ColourGain;

// The colour map's gain at terrain UV uv (0..1 over the tile: the UV the splatmaps use).
half3 TerrathemeColourGain(float2 uv)
{
    return tex2D(_ColourMap, uv * _ColourMap_ST.xy + _ColourMap_ST.zw).rgb * _ColourGain;
}

#endif
