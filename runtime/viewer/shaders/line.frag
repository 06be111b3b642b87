#version 330 core
out vec4 frag;
void main() { frag = vec4(0.1, 0.1, 0.1, 1.0); }
