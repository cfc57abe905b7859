// Terratheme terrain shader (built-in render pipeline, Unity 2019.3 or later; docs/engines.md).
//
// Unity's "Nature/Terrain/Diffuse" (Lambert lighting, TerrainSplatmapCommon.cginc's splat of
// four layers per pass, holes, instancing) with one change: the blended albedo is multiplied by
// the terratheme colour map's gain (TerrathemeColourMap.cginc), as terratheme's renderer does.
// Terrains of more than four layers draw further passes with TerrathemeTerrainAddPass.shader,
// which multiplies its layers by the same gain, so the sum is the splat of all layers times it.
// Beyond the terrain's Base Map Distance Unity draws a baked base map without the colour map:
// the importer sets that distance past the whole terrain. Written without a Unity compiler at
// hand: if Unity reports an error here, please report it with the Unity version.
Shader "Terratheme/Terrain" {
    Properties {
        _ColourMap ("Colour map (colour_map.png, sRGB)", 2D) = "grey" {}
        _ColourGain ("Colour gain (4.633 Linear, 1.992 Gamma)", Float) = 4.633
        // used in fallback on old cards & base map
        [HideInInspector] _MainTex ("BaseMap (RGB)", 2D) = "white" {}
        [HideInInspector] _Color ("Main Color", Color) = (1,1,1,1)
        [HideInInspector] _TerrainHolesTexture ("Holes Map (RGB)", 2D) = "white" {}
    }

    CGINCLUDE
        #pragma surface surf Lambert vertex:SplatmapVert finalcolor:SplatmapFinalColor finalprepass:SplatmapFinalPrepass finalgbuffer:SplatmapFinalGBuffer addshadow fullforwardshadows
        #pragma instancing_options assumeuniformscaling nomatrices nolightprobe nolightmap forwardadd
        #pragma multi_compile_fog
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
            "RenderType" = "Opaque"
            "TerrainCompatible" = "True"
        }
        SubShader { // shader model 3.0 and above
            CGPROGRAM
                #pragma target 3.0
                #pragma multi_compile_local __ _ALPHATEST_ON
                #pragma multi_compile_local __ _NORMALMAP
            ENDCG

            UsePass "Hidden/Nature/Terrain/Utilities/PICKING"
            UsePass "Hidden/Nature/Terrain/Utilities/SELECTION"
        }
        SubShader { // shader model 2.0
            CGPROGRAM
            ENDCG
        }
    }

    Dependency "AddPassShader"    = "Hidden/Terratheme/TerrainAddPass"
    Dependency "BaseMapShader"    = "Hidden/TerrainEngine/Splatmap/Diffuse-Base"
    Dependency "BaseMapGenShader" = "Hidden/TerrainEngine/Splatmap/Diffuse-BaseGen"

    Fallback "Diffuse"
}
