// Terratheme terrain shader, the pass of layers 4 and above (TerrathemeTerrain.shader): Unity's
// "Hidden/TerrainEngine/Splatmap/Diffuse-AddPass" times the colour map's gain, added onto the
// first pass. Written without a Unity compiler at hand (docs/engines.md).
Shader "Hidden/Terratheme/TerrainAddPass" {
    Properties {
        // Unity's terrain fills these from the terrain's material (TerrathemeTerrain.shader).
        [HideInInspector] _ColourMap ("Colour map (colour_map.png, sRGB)", 2D) = "grey" {}
        [HideInInspector] _ColourGain ("Colour gain", Float) = 4.633
    }

    CGINCLUDE
        #pragma surface surf Lambert decal:add vertex:SplatmapVert finalcolor:SplatmapFinalColor finalprepass:SplatmapFinalPrepass finalgbuffer:SplatmapFinalGBuffer fullforwardshadows nometa
        #pragma instancing_options assumeuniformscaling nomatrices nolightprobe nolightmap forwardadd
        #pragma multi_compile_fog
        #define TERRAIN_SPLAT_ADDPASS
        #include "TerrainSplatmapCommon.cginc"
        #include "TerrathemeColourMap.cginc"

        void surf(Input IN, inout SurfaceOutput o)
        {
            half4 splat_control;
            half weight;
            fixed4 mixedDiffuse;
            SplatmapMix(IN, splat_control, weight, mixedDiffuse, o.Normal);
            o.Albedo = mixedDiffuse.rgb * TerrathemeColourGain(IN.tc.xy);
            o.Alpha = weight;
        }
    ENDCG

    Category {
        Tags {
            "Queue" = "Geometry-99"
            "IgnoreProjector" = "True"
            "RenderType" = "Opaque"
        }
        SubShader { // shader model 3.0 and above
            CGPROGRAM
                #pragma target 3.0
                #pragma multi_compile_local __ _ALPHATEST_ON
                #pragma multi_compile_local __ _NORMALMAP
            ENDCG
        }
        SubShader { // shader model 2.0
            CGPROGRAM
            ENDCG
        }
    }

    Fallback off
}
