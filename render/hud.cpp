// The HUD (ImGui window with the run's values) and the colour legend, drawn over a frame.
#include "colormap.hpp"
#include "gl_private.hpp"

#include <imgui.h>
#include <backends/imgui_impl_opengl3.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>

namespace cutsim::render {

PixelRect Renderer::legendRect() const {
    // Right edge, half the height, room for tick labels on its right.
    const float w = static_cast<float>(opts_.width), h = static_cast<float>(opts_.height);
    const float barW = std::max(8.0f, std::round(0.015f * w));
    const float labelW = 62.0f;
    PixelRect r;
    r.x1 = w - labelW - 10.0f;
    r.x0 = r.x1 - barW;
    r.y0 = std::round(0.25f * h);
    r.y1 = std::round(0.75f * h);
    return r;
}

void Renderer::drawHudAndLegend(const RenderSnapshot& snap) {
    Gl& g = *gl_;
    const bool legend = opts_.legend && snap.scalar.size() == snap.vertices() && snap.vertices() > 0;
    const int critical = opts_.xray ? static_cast<int>(snap.criticalTets.cols() / 4) : 0;
    const int answered = opts_.xray ? static_cast<int>(snap.answeredTets.cols() / 4) : 0;
    const bool critLegend = opts_.legend && (critical > 0 || answered > 0);
    if (!legend && !critLegend && !opts_.hud) return;
    ImGui::SetCurrentContext(g.imgui);
    ImGuiIO& io = ImGui::GetIO();
    io.DisplaySize = ImVec2(static_cast<float>(opts_.width), static_cast<float>(opts_.height));
    io.DeltaTime = 1.0f / 30.0f;  // fixed: frames must not depend on wall-clock time

    auto hudWindow = [&] {
        const HudValues& h = snap.hud;
        ImGui::SetNextWindowPos(ImVec2(8, 8));
        ImGui::SetNextWindowBgAlpha(0.6f);
        const ImGuiWindowFlags flags = ImGuiWindowFlags_NoDecoration | ImGuiWindowFlags_AlwaysAutoResize |
                                       ImGuiWindowFlags_NoSavedSettings | ImGuiWindowFlags_NoFocusOnAppearing |
                                       ImGuiWindowFlags_NoNav | ImGuiWindowFlags_NoInputs;
        ImGui::Begin("hud", nullptr, flags);
        // A still mesh (cutsim render) has no time, step or counts to show.
        if (h.simulated) {
            ImGui::Text("t        %.4f s", h.simTime);
            ImGui::Text("dt used  %.3e s", h.dtUsed);
            ImGui::Text("dt cert  %.3e s", h.dtCertified);
            if (std::isnan(h.dtExact))
                ImGui::Text("dt exact n/a");
            else
                ImGui::Text("dt exact %.3e s", h.dtExact);
            if (!std::isnan(h.stepsPerSecond)) {  // NaN: not shown (wall-clock rates differ run to run)
                ImGui::Text("steps/s  %.0f", h.stepsPerSecond);
                ImGui::Text("RT x     %.3f", h.realTimeFactor);
            }
            ImGui::Text("critical %d", h.criticalElements);
            if (h.answeredElements > 0) ImGui::Text("answered %d", h.answeredElements);
            ImGui::Text("cuts     %d", h.cuts);
        }
        for (const auto& line : h.lines) ImGui::TextUnformatted(line.c_str());
        if (!h.forcePlot.empty()) {
            float top = 0;
            for (float f : h.forcePlot) top = std::max(top, f);
            char label[48];
            std::snprintf(label, sizeof label, "max %.3f N", top);
            ImGui::PlotLines("##force", h.forcePlot.data(), static_cast<int>(h.forcePlot.size()), 0, label, 0.0f,
                             top > 0 ? 1.1f * top : 1.0f, ImVec2(220, 60));
        }
        ImGui::End();
    };

    // An auto-resized window takes the size of its previous frame's content (and a new one is
    // hidden on its first frame): lay it out once without drawing, so a line added this frame (a
    // cut's answered count) is inside the panel (layout only: nothing is drawn).
    if (opts_.hud) {
        ImGui_ImplOpenGL3_NewFrame();
        ImGui::NewFrame();
        hudWindow();
        ImGui::Render();
    }

    ImGui_ImplOpenGL3_NewFrame();
    ImGui::NewFrame();
    if (opts_.hud) hudWindow();
    if (legend) {
        // Colour bar: one gradient quad per pair of control points, so the bar is exactly the map.
        ImDrawList* dl = ImGui::GetBackgroundDrawList();
        const PixelRect r = legendRect();
        auto table = colorMapTable(snap.diverging ? ColorMapKind::Diverging : ColorMapKind::Sequential);
        const int segs = static_cast<int>(table.size()) - 1;
        auto col = [](Rgb8 c) { return IM_COL32(c.r, c.g, c.b, 255); };
        for (int i = 0; i < segs; ++i) {
            const float yb = r.y1 - (r.y1 - r.y0) * float(i) / float(segs);
            const float yt = r.y1 - (r.y1 - r.y0) * float(i + 1) / float(segs);
            const ImU32 lo = col(table[static_cast<size_t>(i)]), hi = col(table[static_cast<size_t>(i + 1)]);
            dl->AddRectFilledMultiColor(ImVec2(r.x0, yt), ImVec2(r.x1, yb), hi, hi, lo, lo);
        }
        dl->AddRect(ImVec2(r.x0 - 1, r.y0 - 1), ImVec2(r.x1 + 1, r.y1 + 1), IM_COL32(220, 220, 220, 255));
        // Ticks at the ends, quarters and middle.
        const ImU32 text = IM_COL32(235, 235, 235, 255);
        const float lineH = ImGui::GetTextLineHeight();
        for (int k = 0; k <= 4; ++k) {
            const float y = r.y1 - (r.y1 - r.y0) * float(k) / 4.0f;
            const double v = snap.scalarMin + (snap.scalarMax - snap.scalarMin) * k / 4.0;
            char buf[32];
            std::snprintf(buf, sizeof buf, "%.3g",
                          std::abs(v) < 1e-12 * std::abs(snap.scalarMax - snap.scalarMin) ? 0.0 : v);
            dl->AddLine(ImVec2(r.x1, y), ImVec2(r.x1 + 4, y), text);
            dl->AddText(ImVec2(r.x1 + 7, y - 0.5f * lineH), text, buf);
        }
        std::string title = snap.scalarName;
        if (!snap.scalarUnit.empty()) title += " [" + snap.scalarUnit + "]";
        if (!title.empty()) {
            const float tw = ImGui::CalcTextSize(title.c_str()).x;
            const float x = std::max(4.0f, std::min(r.x0, static_cast<float>(opts_.width) - tw - 6.0f));
            dl->AddText(ImVec2(x, r.y0 - lineH - 6), text, title.c_str());
        }
    }
    if (critLegend) {
        // Swatches under the colour bar: the critical elements, how many and the step they would
        // allow; the ones a recent cut made critical and the step policy answered.
        ImDrawList* dl = ImGui::GetBackgroundDrawList();
        const PixelRect r = legendRect();
        const float lineH = ImGui::GetTextLineHeight();
        const ImU32 text = IM_COL32(235, 235, 235, 255);
        float y = r.y1 + lineH + 2;
        auto swatch = [&](const std::array<std::uint8_t, 3>& c, const char* line1, const char* line2) {
            const float w = std::max(ImGui::CalcTextSize(line1).x, ImGui::CalcTextSize(line2).x) + lineH + 4;
            const float x = std::max(4.0f, std::min(r.x0, static_cast<float>(opts_.width) - w - 4.0f));
            dl->AddRectFilled(ImVec2(x, y + 2), ImVec2(x + lineH - 4, y + lineH - 2), IM_COL32(c[0], c[1], c[2], 255));
            dl->AddText(ImVec2(x + lineH, y), text, line1);
            y += lineH;
            if (line2[0]) {
                dl->AddText(ImVec2(x, y), text, line2);
                y += lineH;
            }
        };
        char line1[48], line2[48];
        if (critical > 0) {
            std::snprintf(line1, sizeof line1, "critical %d", critical);
            if (std::isnan(snap.hud.criticalStep))
                line2[0] = 0;
            else
                std::snprintf(line2, sizeof line2, "dt<=%.2e s", snap.hud.criticalStep);
            swatch(opts_.criticalColour, line1, line2);
        }
        if (answered > 0) {
            std::snprintf(line1, sizeof line1, "answered %d", answered);
            swatch(opts_.answeredColour, line1, "");
        }
    }
    ImGui::Render();
    ImGui_ImplOpenGL3_RenderDrawData(ImGui::GetDrawData());
}

}  // namespace cutsim::render
