// scenes/whitted.json written by hand in POV-Ray 3.7's language, with conventions matched to
// Tessera's renderer (bench/run_all.sh renders it; docs/performance.md, "A peer: POV-Ray 3.7"):
// - coordinates: POV-Ray is left-handed; Tessera's right-handed scene maps to it with z -> -z
//   (the camera then looks along +z, x stays to the right, y up: the image is not mirrored);
// - camera: Tessera's vfov 40 deg becomes POV-Ray's horizontal `angle` for the image aspect;
// - lights: inverse-square falloff. POV-Ray fades by 2 / (1 + (d / fade_distance)^2); with
//   fade_distance F = 0.001 that is 2 F^2 / d^2 to 1 part in 10^7 at these distances, so the
//   light color is I / (2 F^2) / pi (the 1/pi: POV-Ray's diffuse has no Lambertian 1/pi);
// - Lambertian finish: diffuse 1, brilliance 1, no ambient, no specular, no phong;
// - checker floor: Tessera's plane checker is floor(x) + floor(-z) in its own basis; POV-Ray's
//   checker is floor(x) + floor(y) + floor(z), shifted by half a unit in y so floor(y) = 0;
// - glass: ior 1.5, reflection with exact Fresnel (fresnel on), conserve_energy so refraction
//   gets 1 - R, clear filter (shadow rays pass unrefracted and unattenuated, as in Tessera);
// - max_trace_level 9 = the camera ray plus Tessera's max_depth 8 bounces; adc_bailout at
//   POV-Ray's default, 1/255: POV-Ray stops a ray whose weight falls below it (a hard cut-off),
//   where Tessera plays Russian roulette below a weight of 0.01 (image.roulette_weight), so both
//   skip the faint branches of the glass ball's tree as each does by default;
// - assumed_gamma 1.0 and EXR output: linear light throughout.
#version 3.7;
#declare F = 0.001;
#declare Scale = 1 / (2 * F * F) / pi;

global_settings { assumed_gamma 1.0 max_trace_level 9 adc_bailout 1 / 255 ambient_light 0 }

camera {
  perspective
  location <0, 1.6, -6.5>
  look_at <0, 0.9, 0>
  right x * image_width / image_height
  up y
  angle 2 * degrees(atan(tan(radians(20)) * image_width / image_height))
}

background { rgb <0.25, 0.45, 0.8> }

light_source { <-4, 6, -5> color rgb 160 * Scale fade_distance F fade_power 2 }
light_source { <5, 7, 1> color rgb <90, 85, 75> * Scale fade_distance F fade_power 2 }

#declare Lambert = finish { ambient 0 emission 0 diffuse 1 brilliance 1 specular 0 phong 0 }

plane {
  y, 0
  texture {
    pigment { checker color rgb <0.85, 0.1, 0.08> color rgb <0.9, 0.85, 0.15> translate <0, -0.5, 0> }
    finish { Lambert }
  }
}

sphere {  // mirror_ball
  <-1.5, 1.0, 0.8>, 1.0
  texture { pigment { rgb 0 } finish { ambient 0 emission 0 diffuse 0 specular 0 reflection { 0.92 } } }
}

sphere {  // glass_ball
  <0.55, 0.8, -1.4>, 0.8
  material {
    texture {
      pigment { rgbf <1, 1, 1, 1> }
      finish { ambient 0 emission 0 diffuse 0 specular 0 reflection { 0, 1 fresnel on } conserve_energy }
    }
    interior { ior 1.5 }
  }
}

sphere {  // matte_ball
  <2.0, 0.7, 0.6>, 0.7
  texture { pigment { rgb <0.2, 0.5, 0.25> } finish { Lambert } }
}
