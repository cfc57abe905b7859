// Terratheme -> Unity terrain importer (Unity 2019.3 or later; terratheme docs/engines.md).
//
// 1. Copy the whole export folder (terratheme export PROJECT OUTDIR --engine unity) under Assets/.
// 2. Select terratheme_unity.json in the Project window.
// 3. Choose Assets > Terratheme > Build Terrain From Export.
//
// It makes one TerrainLayer per theme (texture, tile size and offset from the JSON), one
// TerrainData asset per tile with the splatmaps' weights (splatmap s holds layers 4s..4s+3 in
// R, G, B, A; the weights of every texel sum to 255), and connected Terrain objects under one
// parent. The splatmap PNGs are read from disk, so Unity's texture import settings never touch
// the weights.
//
// The colour map (colour_map.png: a gain value / 128 per channel over the blended layers) has no
// place in Unity's terrain layers. The script imports it (sRGB, clamped, bilinear, uncompressed)
// and gives every terrain its own material with _ColourMap set, its tiling/offset (_ColourMap_ST)
// set to the tile's colour_map_st and _ColourGain (4.633 in a Linear colour space project,
// 255/128 in Gamma), from the folder's TerrathemeTerrain.mat when there is one (a material of
// your own whose shader has a _ColourMap texture), else, in the built-in render pipeline, from the
// shipped shader Terratheme/Terrain (Shaders/TerrathemeTerrain.shader): Unity's diffuse terrain
// shader times tex2D(_ColourMap, terrainUV * _ColourMap_ST.xy + _ColourMap_ST.zw).rgb * _ColourGain.
// URP and HDRP need TerrathemeTerrain.mat (docs/engines.md). Written without a Unity compiler at
// hand: if Unity reports an error here, please report it with the Unity version.
#if UNITY_EDITOR
using System.IO;
using UnityEditor;
using UnityEngine;
using UnityEngine.Rendering;

public static class TerrathemeImporter
{
    [System.Serializable]
    public class Layer
    {
        public string name;
        public string texture;
        public float[] tile_size;
        public float[] tile_offset;
    }

    [System.Serializable]
    public class Tile
    {
        public int x;
        public int y;
        public float[] position;
        public string[] splatmaps;
        public float[] colour_map_st;
    }

    [System.Serializable]
    public class ColourMap
    {
        public string file;
        public float linear_gain;
    }

    [System.Serializable]
    public class Manifest
    {
        public string format;
        public int alphamap_resolution;
        public int tiles_x;
        public int tiles_y;
        public float[] tile_world_size;
        public Layer[] layers;
        public Tile[] tiles;
        public ColourMap colour_map;
    }

    const string MenuPath = "Assets/Terratheme/Build Terrain From Export";

    [MenuItem(MenuPath, true)]
    static bool CanBuild()
    {
        Object selected = Selection.activeObject;
        return selected != null && AssetDatabase.GetAssetPath(selected).EndsWith("terratheme_unity.json");
    }

    [MenuItem(MenuPath)]
    static void Build()
    {
        string jsonPath = AssetDatabase.GetAssetPath(Selection.activeObject);
        string folder = Path.GetDirectoryName(jsonPath).Replace('\\', '/');
        Manifest manifest = JsonUtility.FromJson<Manifest>(File.ReadAllText(jsonPath));
        if (manifest == null || manifest.format != "terratheme-unity")
        {
            Debug.LogError(jsonPath + ": not a terratheme Unity export");
            return;
        }
        TerrainLayer[] layers = new TerrainLayer[manifest.layers.Length];
        for (int k = 0; k < layers.Length; k++)
        {
            Layer source = manifest.layers[k];
            TerrainLayer layer = new TerrainLayer();
            layer.name = source.name;
            layer.diffuseTexture = AssetDatabase.LoadAssetAtPath<Texture2D>(folder + "/" + source.texture);
            layer.tileSize = new Vector2(source.tile_size[0], source.tile_size[1]);
            layer.tileOffset = new Vector2(source.tile_offset[0], source.tile_offset[1]);
            AssetDatabase.CreateAsset(layer, folder + "/" + source.name + ".terrainlayer");
            layers[k] = layer;
        }
        Texture2D colour;
        Material template = ColourMaterial(folder, manifest, out colour);
        int resolution = manifest.alphamap_resolution;
        float farthest = 4f * (manifest.tile_world_size[0] * manifest.tiles_x
                               + manifest.tile_world_size[1] * manifest.tiles_y);
        GameObject root = new GameObject("Terratheme terrain");
        foreach (Tile tile in manifest.tiles)
        {
            string name = "terrain_x" + tile.x + "_y" + tile.y;
            TerrainData data = new TerrainData();
            data.heightmapResolution = 33;  // before size: setting it rescales the size
            data.alphamapResolution = resolution;
            data.size = new Vector3(manifest.tile_world_size[0], 1f, manifest.tile_world_size[1]);
            data.terrainLayers = layers;
            data.SetAlphamaps(0, 0, ReadWeights(folder, tile.splatmaps, resolution, layers.Length));
            AssetDatabase.CreateAsset(data, folder + "/" + name + ".asset");
            GameObject terrain = Terrain.CreateTerrainGameObject(data);
            terrain.name = name;
            terrain.transform.SetParent(root.transform, false);
            terrain.transform.localPosition = new Vector3(tile.position[0], 0f, tile.position[1]);
            terrain.GetComponent<Terrain>().allowAutoConnect = true;
            if (template != null && tile.colour_map_st != null && tile.colour_map_st.Length == 4)
            {
                Material material = new Material(template);
                material.SetTexture("_ColourMap", colour);
                material.SetTextureScale("_ColourMap", new Vector2(tile.colour_map_st[0], tile.colour_map_st[1]));
                material.SetTextureOffset("_ColourMap", new Vector2(tile.colour_map_st[2], tile.colour_map_st[3]));
                if (material.HasProperty("_ColourGain"))
                    material.SetFloat("_ColourGain", QualitySettings.activeColorSpace == ColorSpace.Linear
                        ? manifest.colour_map.linear_gain : 255f / 128f);
                AssetDatabase.CreateAsset(material, folder + "/" + name + ".mat");
                terrain.GetComponent<Terrain>().materialTemplate = material;
                // Beyond this distance Unity draws a baked base map, without the colour map.
                terrain.GetComponent<Terrain>().basemapDistance = farthest;
            }
        }
        AssetDatabase.SaveAssets();
        Undo.RegisterCreatedObjectUndo(root, "Build terratheme terrain");
        Selection.activeGameObject = root;
    }

    // Imports colour_map.png for sampling as a colour texture; returns the material every terrain
    // gets a copy of: the folder's TerrathemeTerrain.mat when it has a _ColourMap texture, else, in
    // the built-in render pipeline, a material of the shipped Terratheme/Terrain shader; else null
    // (and says what to do).
    static Material ColourMaterial(string folder, Manifest manifest, out Texture2D colour)
    {
        colour = null;
        if (manifest.colour_map == null || string.IsNullOrEmpty(manifest.colour_map.file))
            return null;
        string path = folder + "/" + manifest.colour_map.file;
        TextureImporter importer = AssetImporter.GetAtPath(path) as TextureImporter;
        if (importer != null)
        {
            importer.sRGBTexture = true;
            importer.wrapMode = TextureWrapMode.Clamp;
            importer.filterMode = FilterMode.Bilinear;
            importer.mipmapEnabled = false;
            importer.npotScale = TextureImporterNPOTScale.None;
            importer.textureCompression = TextureImporterCompression.Uncompressed;
            importer.SaveAndReimport();
        }
        colour = AssetDatabase.LoadAssetAtPath<Texture2D>(path);
        Material template = AssetDatabase.LoadAssetAtPath<Material>(folder + "/TerrathemeTerrain.mat");
        if (template != null && template.HasProperty("_ColourMap"))
            return template;
        if (template != null)
            Debug.LogWarning(folder + "/TerrathemeTerrain.mat: its shader has no _ColourMap texture");
        Shader shipped = Shader.Find("Terratheme/Terrain");
        if (GraphicsSettings.currentRenderPipeline == null && shipped != null)
            return new Material(shipped);
        Debug.Log(path + ": imported. To show the colour map "
            + (shipped == null ? "copy the export's Shaders folder too, or " : "in URP or HDRP, ")
            + "save a terrain material whose shader has a _ColourMap texture as TerrathemeTerrain.mat "
            + "in this folder and build again (docs/engines.md)");
        return null;
    }

    // Texture2D.LoadImage puts the PNG's top row (north) at the top; GetPixels32 returns rows
    // bottom (south) first, which is the order of TerrainData's alphamap rows (z = 0 first).
    static float[,,] ReadWeights(string folder, string[] files, int resolution, int count)
    {
        float[,,] maps = new float[resolution, resolution, count];
        for (int s = 0; s < files.Length; s++)
        {
            Texture2D image = new Texture2D(2, 2, TextureFormat.RGBA32, false, true);
            bool loaded = image.LoadImage(File.ReadAllBytes(folder + "/" + files[s]));
            if (!loaded || image.width != resolution || image.height != resolution)
                throw new System.Exception(files[s] + ": not a " + resolution + " x " + resolution + " splatmap");
            Color32[] pixels = image.GetPixels32();
            Object.DestroyImmediate(image);
            for (int c = 0; c < 4 && 4 * s + c < count; c++)
                for (int y = 0; y < resolution; y++)
                    for (int x = 0; x < resolution; x++)
                    {
                        Color32 p = pixels[y * resolution + x];
                        byte v = c == 0 ? p.r : c == 1 ? p.g : c == 2 ? p.b : p.a;
                        maps[y, x, 4 * s + c] = v / 255f;
                    }
        }
        return maps;
    }
}
#endif
